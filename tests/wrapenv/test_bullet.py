"""The world of boxes (`wrapenv.bullet`) against hand-computed friction limits."""

from __future__ import annotations

import math
import tempfile

import numpy as np
import pytest

from wrapenv.bullet import BulletWorld, _rigid_world_bytes, _step_velocities, rotation_matrices
from wrapenv.profile import G

BOX_M = (0.28, 0.19, 0.33)
BOX_KG = 9.3
MU = 0.7  # each body's coefficient; Bullet's contact uses their product, 0.49
#: Bullet holds a box on a floor by its four corner contact points, each a half-diagonal from
#: the centre and bearing a quarter of the weight on average: the twist friction can hold is
#: mu² m g r = 0.49 x 9.3 kg x 9.81 m/s² x 0.169 m = 7.6 N m.
TWIST_LIMIT_N_M = MU**2 * BOX_KG * G * math.hypot(BOX_M[0] / 2, BOX_M[1] / 2)


def turn_deg(rigid: bool, torque_n_m: float, seconds: float = 5.0) -> float:
    """How far a box on a still floor turns about the vertical under a torque about it,
    ramped up over 0.2 s and then held, given as the bench gives the wrap's torques."""
    with BulletWorld(1 / 240, 50, rigid=rigid) as world:
        world.add_box((4.0, 4.0, 0.1), (0.0, 0.0, -0.05), 0.0, MU)
        box = world.add_box(BOX_M, (0.0, 0.0, BOX_M[2] / 2), BOX_KG, MU)
        steps = round(seconds / world.timestep_s)
        for step in range(steps):
            pos, quat = world.poses([box])
            torque = np.array([[0.0, 0.0, torque_n_m * min(1.0, step / 48)]])
            world.apply_wrenches([box], pos, np.zeros((1, 3)), torque, rotation_matrices(quat))
            world.step()
        rot = rotation_matrices(world.poses([box])[1])[0]
    return math.degrees(math.atan2(rot[1, 0], rot[0, 0]))


#: Past the limit by how much a box must turn: a reduced-coordinate body's friction is a cone
#: (|f| <= mu N), a rigid body's a box (each of two directions <= mu N), which holds up to
#: sqrt(2) times as much where the force is diagonal to its directions.
BEYOND = {False: 1.1, True: 1.5}


@pytest.mark.parametrize("rigid", [False, True], ids=["reduced", "rigid"])
def test_static_friction_holds_a_twist_below_its_limit_and_not_above(rigid):
    # Bullet's rigid-body friction leaves an external torque out of what it holds still, so a
    # rigid box given its torque as an external torque crept round at tau dt² / I per step
    # (27 degrees in 10 s at 1 N m): the world gives it as a velocity instead.
    assert abs(turn_deg(rigid, 0.9 * TWIST_LIMIT_N_M)) < 0.01
    assert abs(turn_deg(rigid, BEYOND[rigid] * TWIST_LIMIT_N_M)) > 10.0


def test_a_rigid_world_leaves_no_file_behind(tmp_path, monkeypatch):
    # the solver mode reaches a rigid world through a saved world on disk: made and loaded in
    # temporary folders that are gone once the world is built (searches build thousands)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    _rigid_world_bytes.cache_clear()
    for _ in range(3):
        with BulletWorld(1 / 240, 20, rigid=True) as world:
            world.add_box(BOX_M, (0.0, 0.0, BOX_M[2] / 2), BOX_KG, MU)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("rigid", [False, True], ids=["reduced", "rigid"])
def test_a_torque_spins_a_free_box_at_its_inverse_inertia(rigid):
    # One step from rest under a torque tau (world frame): w = dt I_world^-1 tau, with
    # I_world = R diag(I) R^T and a box's I = m/12 (b² + c², a² + c², a² + b²). A turned box
    # checks the frames a rigid body's torque goes through (BulletWorld._turn). A rigid body
    # takes the velocity before the step, so Bullet's gyroscopic term already acts on it within
    # the step: second order, 2e-4 of it here.
    a, b, c = BOX_M
    inertia = BOX_KG / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    torque = np.array([1.0, -2.0, 0.5])
    with BulletWorld(1 / 240, 20, rigid=rigid) as world:
        box = world.add_box(BOX_M, (0.0, 0.0, 5.0), BOX_KG, MU)  # far above anything
        turned = (0.2397, -0.2099, 0.4794, 0.8178)  # a unit quaternion (x y z w), all axes
        world.set_pose(box, (0.0, 0.0, 5.0), turned)
        rot = rotation_matrices(world.poses([box])[1])
        world.apply_wrenches([box], np.array([[0.0, 0.0, 5.0]]), np.zeros((1, 3)),
                             torque[None], rot)
        world.step()
        omega = world.velocities([box])[1][0]
    expected = world.timestep_s * rot[0] @ ((rot[0].T @ torque) / inertia)
    np.testing.assert_allclose(omega, expected, rtol=1e-3)


def _about(axis: tuple[float, float, float], angle_rad: float) -> np.ndarray:
    """The unit quaternion (x y z w) of a turn by `angle_rad` about `axis`."""
    unit = np.array(axis) / np.linalg.norm(axis)
    return np.array([*(unit * math.sin(angle_rad / 2)), math.cos(angle_rad / 2)])


def _times(q1: np.ndarray, q0: np.ndarray) -> np.ndarray:
    """The quaternion product q1 q0 (x y z w): q0's turn, then q1's."""
    v1, w1, v0, w0 = q1[:3], q1[3], q0[:3], q0[3]
    return np.array([*(w1 * v0 + w0 * v1 + np.cross(v1, v0)), w1 * w0 - v1 @ v0])


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["q", "-q"])
def test_one_step_of_poses_gives_the_rotation_vector_over_the_step(sign):
    """From a body turned anyhow, a further 0.3 rad about (1, 2, 2)/3 in a step of 1/240 s is
    an angular velocity of 0.3 x 240 = 72 rad/s along that axis, world frame; the same if the
    second pose is written -q (one rotation, two quaternions); and (x1 - x0) / dt."""
    dt = 1 / 240
    q0 = _about((0.3, -1.0, 0.5), 1.1)
    q1 = sign * _times(_about((1.0, 2.0, 2.0), 0.3), q0)
    x0, x1 = np.array([[0.1, 0.2, 0.3]]), np.array([[0.1 + 0.01, 0.2, 0.3 - 0.002]])
    vel, omega = _step_velocities(x0, q0[None], x1, q1[None], dt)
    np.testing.assert_allclose(vel, [[2.4, 0.0, -0.48]], rtol=1e-12)
    np.testing.assert_allclose(omega, [[24.0, 48.0, 48.0]], rtol=1e-12)
    _, still = _step_velocities(x0, q0[None], x0, -q0[None], dt)
    np.testing.assert_allclose(still, np.zeros((1, 3)), atol=1e-12)


@pytest.mark.parametrize("rigid", [False, True], ids=["reduced", "rigid"])
def test_state_of_a_tumbling_box_is_bullets_own_velocities(rigid):
    """`state` takes velocities from consecutive poses; a box tumbling freely (6.7 rad/s,
    its axis precessing) checks the rotation part where a bench level's bodies barely turn."""
    with BulletWorld(1 / 240, 20, rigid=rigid) as world:
        box = world.add_box(BOX_M, (0.0, 0.0, 5.0), BOX_KG, MU)
        pos, quat = world.poses([box])
        world.apply_wrenches([box], pos, np.zeros((1, 3)), np.array([[150.0, -100.0, 50.0]]),
                             rotation_matrices(quat))
        world.step()
        errors, speeds = [], []
        for _ in range(30):
            _, _, lin, ang = world.state([box])
            own_lin, own_ang = world.velocities([box])
            errors.append(max(np.abs(lin - own_lin).max(), np.abs(ang - own_ang).max()))
            speeds.append(float(np.linalg.norm(own_ang)))
            world.step()
    assert min(speeds) > 5.0
    assert max(errors) < 1e-9


def test_state_asks_bullet_for_velocities_only_when_poses_cannot_give_them(monkeypatch):
    """The finite difference saves a pybullet call per body, the point of `state`; it holds for
    the same bodies one step after the last reading, not after two steps or for other bodies."""
    with BulletWorld(1 / 240, 20) as world:
        boxes = [world.add_box(BOX_M, (x, 0.0, 5.0), BOX_KG, MU) for x in (0.0, 1.0)]
        asked = []
        own = world.velocities

        def counted(indices):
            asked.append(indices)
            return own(indices)

        monkeypatch.setattr(world, "velocities", counted)
        world.state(boxes)
        world.step()
        world.state(boxes)
        assert len(asked) == 1
        world.step()
        world.state(boxes[:1])
        world.step()
        world.step()
        world.state(boxes[:1])
        assert asked == [boxes, boxes[:1], boxes[:1]]


def test_penetration_is_the_deepest_overlap_bullet_reports():
    """0 with nothing touching; a box resting on the floor overlaps it by Bullet's contact
    margin at most (under 1 mm); one set tilted into the floor, one edge 30 mm deep and the
    other 10 mm, reads 30 mm after a step (the depth Bullet's collision pass finds, before the
    solver pushes it out): tilted by asin(20 mm / 280 mm) about y, its centre at
    -30 mm + (h/2) cos + (l/2) sin."""
    with BulletWorld(1 / 240, 20) as world:
        world.add_box((4.0, 4.0, 0.1), (0.0, 0.0, -0.05), 0.0, MU)
        box = world.add_box(BOX_M, (0.0, 0.0, 1.0), BOX_KG, MU)
        world.step()
        assert world.max_penetration_m() == 0.0
        world.set_pose(box, (0.0, 0.0, BOX_M[2] / 2), (0.0, 0.0, 0.0, 1.0))
        for _ in range(240):
            world.step()
        assert 0.0 <= world.max_penetration_m() < 1e-3
        tilt = math.asin(0.02 / BOX_M[0])
        centre_z = -0.03 + BOX_M[2] / 2 * math.cos(tilt) + BOX_M[0] / 2 * math.sin(tilt)
        world.set_pose(box, (0.0, 0.0, centre_z), (0.0, math.sin(tilt / 2), 0.0,
                                                  math.cos(tilt / 2)))
        world.step()
        assert world.max_penetration_m() == pytest.approx(0.03, abs=1e-3)

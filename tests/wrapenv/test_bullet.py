"""The world of boxes (`wrapenv.bullet`) against hand-computed friction limits, and its clients
reused bit for bit."""

from __future__ import annotations

import hashlib
import math
import multiprocessing
import tempfile

import numpy as np
import pybullet as pb
import pytest

from wrapenv import bullet
from wrapenv.bench import SimSettings, run_level
from wrapenv.bullet import BulletWorld, _rigid_world_bytes, rotation_matrices
from wrapenv.load import LoadUnit
from wrapenv.profile import G, PulseProfile
from wrapenv.wrap import WrapFormat

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


#: Levels that turn a last-bit difference into another run (tests/wrapenv/test_bench_health.py):
#: the 2-layer example's top layer sliding off at 0.45 g, bare and Kraft-wrapped, and with
#: rigid boxes, whose world loads a saved solver mode into its client.
_CHAOTIC = (("bare", False), ("kraft", False), ("bare", True))


def _chaotic_digest(wrapped: str, rigid: bool) -> str:
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    wrap = (WrapFormat.from_toml("examples/wrap_kraft_2layer.toml", load.load_height_m)
            if wrapped == "kraft" else None)
    trace = run_level(load.layout(), PulseProfile(0.45), SimSettings(rigid_boxes=rigid),
                      wrap=wrap)
    return hashlib.sha256(trace.bundle_pos_m.tobytes()).hexdigest()


def _world_left_odd() -> None:
    """A world that changes what it can of its client's solve, steps and closes."""
    with BulletWorld(1 / 90, 3, contact_erp=0.9) as world:
        world._client.setPhysicsEngineParameter(globalCFM=0.01, frictionERP=0.5,
                                                enableConeFriction=0)
        world.add_box((4.0, 4.0, 0.1), (0.0, 0.0, -0.05), 0.0, MU)
        world.add_box(BOX_M, (0.0, 0.0, 0.5), BOX_KG, MU)
        for _ in range(20):
            world.step()


@pytest.mark.parametrize(("wrapped", "rigid"), _CHAOTIC)
def test_a_world_on_a_reused_client_runs_bit_for_bit_as_on_a_new_one(wrapped, rigid,
                                                                      monkeypatch):
    bullet.disconnect_idle_clients()
    monkeypatch.setattr(bullet, "MAX_IDLE_CLIENTS", 0)
    new = _chaotic_digest(wrapped, rigid)
    monkeypatch.setattr(bullet, "MAX_IDLE_CLIENTS", 2)
    _world_left_odd()
    reused = list(bullet._IDLE_CLIENTS)
    assert len(reused) == 1
    assert _chaotic_digest(wrapped, rigid) == new
    assert bullet._IDLE_CLIENTS == reused   # the level took that client and gave it back


def test_closed_worlds_keep_at_most_a_few_clients_and_disconnect_the_rest():
    bullet.disconnect_idle_clients()
    worlds = [BulletWorld(1 / 240, 50) for _ in range(bullet.MAX_IDLE_CLIENTS + 2)]
    clients = [world._client for world in worlds]
    for world in worlds:
        world.close()
    connected = [client for client in clients if pb.isConnected(client._client)]
    assert connected == bullet._IDLE_CLIENTS and len(connected) == bullet.MAX_IDLE_CLIENTS
    bullet.disconnect_idle_clients()
    assert not any(pb.isConnected(client._client) for client in clients)


def _idle_in_child(queue: multiprocessing.Queue) -> None:
    queue.put(len(bullet._IDLE_CLIENTS))


def test_a_forked_process_does_not_inherit_idle_clients():
    BulletWorld(1 / 240, 50).close()
    assert bullet._IDLE_CLIENTS
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_idle_in_child, args=(queue,))
    child.start()
    child.join(timeout=30)
    assert child.exitcode == 0 and queue.get(timeout=5) == 0
    assert bullet._IDLE_CLIENTS   # the parent's are its own still

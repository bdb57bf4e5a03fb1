"""Would rigid (maximal-coordinate) boxes make the bench cheaper? (issue 15)

The bench's boxes are reduced-coordinate bodies (`btMultiBody`), whose contacts Bullet does not
warm-start. Rigid bodies are warm-started, but a box sliding on a dynamic one veers and slides
short. pybullet's solver mode already holds two friction directions
(SOLVER_USE_2_FRICTION_DIRECTIONS); the veer comes from directions that follow the sliding
velocity, which SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION turns off. That flag, like
the warm-start one, is reached through a saved world's solver mode (`bench_warm_start`).

Compared, each case on the bench as it is and with rigid boxes (with and without the flag,
and with it but not warm-started: `warmStartingFactor` 0): the closed-form slide of
tests/wrapenv/test_bench_mechanics.py at 0.6 g; the 2- and 3-layer columnar examples unwrapped
at 0.3 g; the 3-layer example in Kraft bands at 0.5 g, and at 0.05 g, which moves nothing on
the bench (is a squeezed rigid stack stable by itself?); the wrapped cases also with the wrap's
torques left out (its forces kept), on the bench and on rigid boxes, and on rigid boxes with
only its torque about the vertical left out or kept: a different model, run only to find what a
squeezed rigid stack cannot bear. First, whether a lone box's static friction holds a twist
about the vertical, with and without friction anchors: a rigid box does not, because Bullet's
rigid-body friction leaves an external torque out (`BulletWorld._turn`), unless the torque is
given as the angular velocity it adds. Then whether a lone box slides along a pull across a
floor at the closed-form rate: with the flag, a rigid box's friction holds each of two
world-fixed directions apart (a pyramid, where a reduced-coordinate body's is a cone). So last,
rigid boxes as the bench builds them with `SimSettings.rigid_boxes`: the flag set, torques given
as velocities. Per case:
CPU s, the bundles' largest displacement along the motion at the end and how far and when a
bundle rose (a squeezed stack coming apart), or why the run became unphysical.

    taskset -c 0 python -m benchmarks.bench_rigid
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as pb

from benchmarks.bench_speed import slip_error
from benchmarks.bench_warm_start import worlds_loaded_from
from wrapenv.bench import SimSettings, run_level
from wrapenv.bullet import (
    SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION,
    BulletWorld,
    G,
    solver_mode_world,
)
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat

CASES = (  # (name, load, wrap, level g)
    ("2 layers, 0.3 g", "examples/pet_2layer_columnar.toml", None, 0.3),
    ("3 layers, 0.3 g", "examples/pet_3layer_columnar.toml", None, 0.3),
    ("3 layers, Kraft bands, 0.5 g", "examples/pet_3layer_columnar.toml",
     "examples/wrap_kraft_3layer.toml", 0.5),
    ("3 layers, Kraft bands, 0.05 g", "examples/pet_3layer_columnar.toml",
     "examples/wrap_kraft_3layer.toml", 0.05),
)


@dataclass(frozen=True)
class Variant:
    """How the bench's worlds are built: loaded from a saved world (None: as they are), with
    rigid boxes, engine parameters set after the bench's own, and which components (world x,
    y, z) of the wrap's torques are applied (others left out: a different model, only to find
    what a rigid stack cannot bear)."""

    label: str
    world: Path | None
    rigid: bool
    parameters: dict[str, Any] = field(default_factory=dict)
    torque_axes: tuple[float, float, float] = (1.0, 1.0, 1.0)
    settings: SimSettings = SimSettings()

    @property
    def torques(self) -> bool:
        """Whether the wrap's torques are applied whole."""
        return self.torque_axes == (1.0, 1.0, 1.0)

    @contextlib.contextmanager
    def worlds(self) -> Iterator[None]:
        with worlds_loaded_from(self.world, self.rigid, self.parameters):
            if self.torques:
                yield
                return
            apply, axes = BulletWorld.apply_wrenches, np.array(self.torque_axes)

            def some_torques(world: BulletWorld, indices: Sequence[int] | np.ndarray,
                             centres: np.ndarray, forces: np.ndarray, torques: np.ndarray,
                             rotations: np.ndarray) -> None:
                apply(world, indices, centres, forces, torques * axes, rotations)

            BulletWorld.apply_wrenches = some_torques  # type: ignore[method-assign,assignment]
            try:
                yield
            finally:
                BulletWorld.apply_wrenches = apply  # type: ignore[method-assign]


def case(load: LoadUnit, wrap: WrapFormat | None, level_g: float,
         settings: SimSettings | None = None) -> tuple[float, str]:
    """CPU s, and the largest displacement along the motion or why the run is invalid."""
    t0 = time.process_time()
    trace = run_level(load.layout(), PulseProfile(level_g), settings or SimSettings(), wrap=wrap)
    cpu = time.process_time() - t0
    dx = trace.bundle_pos_m[-1, :, 0] - trace.bundle_pos_m[0, :, 0]
    rise = trace.bundle_pos_m[:, :, 2] - trace.bundle_pos_m[0, :, 2]
    if not trace.valid:
        return cpu, f"invalid: {trace.invalid_reason}"
    return cpu, (f"{1e3 * np.max(np.abs(dx)):.1f} mm, a bundle rose {1e3 * np.max(rise):.1f} mm"
                 f" at most (first by 10 mm at {_first(trace.t_s, np.max(rise, axis=1))})")


def _first(t_s: np.ndarray, rise_m: np.ndarray) -> str:
    """When a bundle first rose 10 mm above where the level found it."""
    above = np.flatnonzero(rise_m > 0.01)
    return f"{t_s[above[0]]:.2f} s" if len(above) else "no time"


#: the twist check: a bundle-sized box on a still floor, twisted about the vertical by torques
#: below what its friction holds: 0.7 x 9.3 kg x g = 64 N at a lever between the mean distance
#: of its footprint from the centre (~0.08 m: 5 N m) and its corners, where Bullet's contact
#: points lie (0.17 m: 11 N m)
TWIST_TORQUES_N_M = (2.0, 5.0)
TWIST_STEPS = 2400  # 10 s at the bench's 1/240 s


def twist_deg(rigid: bool, anchored: bool, torque_n_m: float,
              as_velocity: bool = False) -> tuple[float, float]:
    """How far (degrees) a lone box on a floor turns under a torque about the vertical after 2 s
    and 10 s: static friction should hold it still. `as_velocity`: the torque given as the
    angular velocity it adds in a step, as `BulletWorld` gives it to a rigid body."""
    client = pb.connect(pb.DIRECT)
    try:
        pb.setTimeStep(1 / 240, physicsClientId=client)
        pb.setGravity(0, 0, -9.81, physicsClientId=client)
        pb.setPhysicsEngineParameter(numSolverIterations=50, physicsClientId=client)
        floor = pb.createMultiBody(0, pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=[2, 2, 0.05], physicsClientId=client), -1, [0, 0, -0.05],
            useMaximalCoordinates=rigid, physicsClientId=client)
        box = pb.createMultiBody(9.3, pb.createCollisionShape(
            pb.GEOM_BOX, halfExtents=[0.14, 0.095, 0.165], physicsClientId=client), -1,
            [0, 0, 0.165], useMaximalCoordinates=rigid, physicsClientId=client)
        for body in (floor, box):
            pb.changeDynamics(body, -1, lateralFriction=0.7, restitution=0.0,
                              linearDamping=0.0, angularDamping=0.0,
                              frictionAnchor=int(anchored),
                              activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING,
                              physicsClientId=client)
        yaw = []
        inertia_z = pb.getDynamicsInfo(box, -1, physicsClientId=client)[2][2]
        for step in range(TWIST_STEPS):
            torque = torque_n_m * min(1.0, step / 48)
            if as_velocity:
                wx, wy, wz = pb.getBaseVelocity(box, physicsClientId=client)[1]
                pb.resetBaseVelocity(box, angularVelocity=[wx, wy, wz + torque / 240 / inertia_z],
                                     physicsClientId=client)
            else:
                pb.applyExternalTorque(box, -1, [0, 0, torque], pb.WORLD_FRAME,
                                       physicsClientId=client)
            pb.stepSimulation(physicsClientId=client)
            if step + 1 in (TWIST_STEPS // 5, TWIST_STEPS):
                quat = pb.getBasePositionAndOrientation(box, physicsClientId=client)[1]
                yaw.append(float(np.degrees(pb.getEulerFromQuaternion(quat)[2])))
    finally:
        pb.disconnect(client)
    return yaw[0], yaw[1]


#: the slide check: a bundle-sized box on a still floor (coefficients 0.7 each: 0.49 combined),
#: its friction anchors dropped as the bench drops a sliding body's, pulled at 0.8 g for 0.5 s
#: at these angles to the x axis: it should slide along the pull at (0.8 - 0.49) g
SLIDE_ANGLES_DEG = (0.0, 22.5, 45.0)
SLIDE_G = 0.8


def slide(rigid: bool, angle_deg: float) -> tuple[float, float]:
    """The box's mean acceleration (m/s²) and direction (degrees from x) sliding under a pull
    at `angle_deg`, in a world as the bench builds it (`rigid`: `SimSettings.rigid_boxes`)."""
    with BulletWorld(1 / 240, 50, rigid=rigid) as world:
        world.add_box((4.0, 4.0, 0.1), (0.0, 0.0, -0.05), 0.0, 0.7)
        box = world.add_box((0.28, 0.19, 0.33), (0.0, 0.0, 0.165), 9.3, 0.7)
        for _ in range(60):
            world.step()
        for index in (0, box):
            world.set_anchored(index, False)
        world.refresh_contacts([0, box])
        world.step()
        start = world.poses([box])[0][0]
        angle = np.radians(angle_deg)
        pull = SLIDE_G * G * np.array([np.cos(angle), np.sin(angle)])
        # a pull across the sled's axis, which BulletWorld does not offer (benchmark only)
        pb.setGravity(-pull[0], -pull[1], -G, physicsClientId=world._id)
        for _ in range(120):
            world.step()
        moved = start[:2] - world.poses([box])[0][0][:2]
    return 2 * float(np.linalg.norm(moved)) / 0.5**2, float(np.degrees(np.arctan2(*moved[::-1])))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per case, alternated")
    args = parser.parse_args(argv)
    print(f"a box pulled at {SLIDE_G} g across a floor (combined coefficient 0.49), its "
          f"acceleration (closed form {(SLIDE_G - 0.49) * G:.2f} m/s^2) and direction:")
    for angle in SLIDE_ANGLES_DEG:
        print(f"  pulled at {angle} deg: " + ", ".join(
            "{}: {:.2f} m/s^2 at {:.1f} deg".format(kind, *slide(rigid, angle))
            for kind, rigid in (("reduced coordinates", False), ("rigid boxes", True))))
    for torque in TWIST_TORQUES_N_M:
        print(f"a box twisted by {torque} N m on a floor (its friction holds 5-11 N m), its "
              "turn after 2 s and 10 s:")
        for rigid, as_velocity in ((False, False), (True, False), (True, True)):
            for anchored in (True, False):
                early, late = twist_deg(rigid, anchored, torque, as_velocity)
                how = "rigid" if rigid else "reduced coordinates"
                print(f"  {how}{', as a velocity' if as_velocity else ''}, friction anchors "
                      f"{'on' if anchored else 'off'}: {early:.3f} deg, {late:.3f} deg",
                      flush=True)
    with tempfile.TemporaryDirectory() as folder:
        plain = solver_mode_world(Path(folder), 0)
        steady = solver_mode_world(Path(folder),
                                   SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION)
        variants = (
            Variant("the bench (reduced coordinates)", None, False),
            Variant("rigid boxes", plain, True),
            Variant("rigid, friction directions not from velocity", steady, True),
            Variant("the same, not warm-started", steady, True, {"warmStartingFactor": 0.0}),
            Variant("rigid, torques as velocities (SimSettings.rigid_boxes)", None, False,
                    settings=SimSettings(rigid_boxes=True)),
            Variant("the bench, the wrap's torques left out", None, False,
                    torque_axes=(0.0, 0.0, 0.0)),
            Variant("rigid, directions not from velocity, the wrap's torques left out", steady,
                    True, torque_axes=(0.0, 0.0, 0.0)),
            Variant("the same, only its torque about the vertical left out", steady, True,
                    torque_axes=(1.0, 1.0, 0.0)),
            Variant("the same, only its torque about the vertical kept", steady, True,
                    torque_axes=(0.0, 0.0, 1.0)))
        print("closed-form slide at 0.6 g: " + ", ".join(
            f"{v.label} {_slip(v)}" for v in variants if v.torques))
        for name, load_path, wrap_path, level_g in CASES:
            load = LoadUnit.from_toml(load_path)
            wrap = WrapFormat.from_toml(wrap_path, load.load_height_m) if wrap_path else None
            cpu: dict[str, list[float]] = {v.label: [] for v in variants}
            end: dict[str, str] = {}
            for _ in range(args.repeat):
                for v in variants:
                    if wrap is None and not v.torques:
                        continue  # no wrap: no torques to leave out
                    with v.worlds():
                        seconds, end[v.label] = case(load, wrap, level_g, v.settings)
                    cpu[v.label].append(seconds)
            base = statistics.median(cpu[variants[0].label])
            print(f"{name} (CPU s, median of {args.repeat}; the end of the last run):")
            for v in variants:
                if cpu[v.label]:
                    median = statistics.median(cpu[v.label])
                    print(f"  {v.label}: {median:.2f} s ({median / base:.2f} x), "
                          f"{end[v.label]}", flush=True)


def _slip(variant: Variant) -> str:
    with variant.worlds():
        return slip_error(variant.settings)


if __name__ == "__main__":
    main()

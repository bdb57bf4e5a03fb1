"""The only module that talks to PyBullet: a world of boxes in the sled's frame.

The bench is simulated in the frame of the sled. A translating sled with acceleration a(t) is
exactly equivalent to a uniform inertial field -a(t) added to gravity (d'Alembert), so the sled is
a static box and each step sets gravity to (-a, 0, -g). This avoids driving a kinematic body,
which Bullet's constraint solver treats as fixed (zero velocity) when it computes friction.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import struct
import sys
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from wrapenv.profile import G

#: What the numpy side hands to Bullet (body friction coefficients, wrap forces and torques) is
#: rounded to these many decimals (coefficients; newtons and newton-metres). numpy's linear
#: algebra and its vectorised functions round differently in their last bits from one processor
#: to another (OpenBLAS's AVX-512 kernels against its AVX2 ones, numpy's AVX-512 loops), and a
#: stack on the bench is chaotic enough to turn 1e-16 into another run: unrounded, the 2-layer
#: example at 0.45 g slid its top layer 0.46 m with one kernel and 0.54 m with the other. Rounded
#: well below anything physical, every processor hands Bullet the same numbers, and Bullet's own
#: arithmetic is the same everywhere, so the same inputs give the same results on every machine.
FRICTION_DECIMALS = 9
WRENCH_DECIMALS = 6
#: The angular velocity a torque adds to a rigid body in a step (rad/s), rounded likewise.
VELOCITY_DECIMALS = 9
#: btContactSolverInfo's solver mode flag: friction directions not taken from the sliding
#: velocity (Bullet's btContactSolverInfo.h). Without it a rigid box sliding on another dynamic
#: box veers and spins, sliding 28 % short of the closed form (benchmarks/bench_rigid.py).
SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION = 64
#: a solver iteration count no world has, to find the solver info in a saved world's bytes
_MARKER_ITERATIONS = 987654
#: TinyRenderer's light for drawn frames: from the camera's side and above; faces shaded by
#: their orientation only (steady colours for the trackers)
LIGHT_DIRECTION, LIGHT_AMBIENT, LIGHT_DIFFUSE = (0.3, -1.0, 0.8), 0.6, 0.4
#: pybullet's residual threshold (PhysicsServerCommandProcessor), which loading a world resets
_PYBULLET_RESIDUAL_THRESHOLD = 1e-7


_LIBC = ctypes.CDLL(None)


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence the C-level prints of PyBullet ("pybullet build time", "argv[0]=")."""
    fds = [1, 2]  # the process's own descriptors, whatever sys.stdout has been replaced by
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(AttributeError, OSError, ValueError):
            stream.flush()
    saved = [os.dup(fd) for fd in fds]
    with open(os.devnull, "wb") as null:
        for fd in fds:
            os.dup2(null.fileno(), fd)
        try:
            yield
        finally:
            _LIBC.fflush(None)
            for fd, copy in zip(fds, saved, strict=True):
                os.dup2(copy, fd)
                os.close(copy)


with _quiet_stdout():
    import pybullet as pb
    from pybullet_utils import bullet_client


def _quaternion_products_to_rotation() -> np.ndarray:
    """(16, 9): each rotation matrix entry as weights of the products q_i q_j of a unit
    quaternion (x, y, z, w), row 4 i + j; the diagonal uses 1 = xx + yy + zz + ww."""
    x, y, z, w = range(4)
    entries = {
        (0, 0): ((x, x, 1), (w, w, 1), (y, y, -1), (z, z, -1)),
        (1, 1): ((y, y, 1), (w, w, 1), (x, x, -1), (z, z, -1)),
        (2, 2): ((z, z, 1), (w, w, 1), (x, x, -1), (y, y, -1)),
        (0, 1): ((x, y, 2), (z, w, -2)), (1, 0): ((x, y, 2), (z, w, 2)),
        (0, 2): ((x, z, 2), (y, w, 2)), (2, 0): ((x, z, 2), (y, w, -2)),
        (1, 2): ((y, z, 2), (x, w, -2)), (2, 1): ((y, z, 2), (x, w, 2)),
    }
    m = np.zeros((4, 4, 3, 3))
    for (row, col), terms in entries.items():
        for i, j, weight in terms:
            m[i, j, row, col] = weight
    return m.reshape(16, 9)


_QUAT_TO_ROT = _quaternion_products_to_rotation()


def rotation_matrices(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) from unit quaternions (n, 4) in Bullet's x y z w order:
    one product with `_QUAT_TO_ROT` instead of nine columns assembled per step."""
    products = (quat[:, :, None] * quat[:, None, :]).reshape(-1, 16)
    return (products @ _QUAT_TO_ROT).reshape(-1, 3, 3)


def _step_velocities(pos0: np.ndarray, quat0: np.ndarray, pos1: np.ndarray, quat1: np.ndarray,
                     dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear and angular (world frame) velocities that carry poses 0 to poses 1 in one step:
    (x1 - x0) / dt, and the rotation vector of q1 conj(q0) over dt."""
    x0, y0, z0, w0 = (-quat0[:, 0], -quat0[:, 1], -quat0[:, 2], quat0[:, 3])  # conj(q0)
    x1, y1, z1, w1 = quat1.T
    turn = np.empty((len(quat1), 3))
    turn[:, 0] = w1 * x0 + x1 * w0 + y1 * z0 - z1 * y0
    turn[:, 1] = w1 * y0 - x1 * z0 + y1 * w0 + z1 * x0
    turn[:, 2] = w1 * z0 + x1 * y0 - y1 * x0 + z1 * w0
    w = w1 * w0 - x1 * x0 - y1 * y0 - z1 * z0
    turn *= np.sign(w + (w == 0))[:, None]  # the shorter way round: q and -q are one rotation
    sin_half = np.sqrt(np.einsum("nk,nk->n", turn, turn))
    # angle / sin(angle / 2), with its limit 2 for no rotation
    scale = 2 * np.arctan2(sin_half, np.abs(w)) / np.where(sin_half > 0, sin_half, 1.0)
    scale[sin_half == 0] = 2.0
    return (pos1 - pos0) / dt_s, turn * (scale / dt_s)[:, None]


def saved_empty_world(path: Path) -> tuple[bytearray, int]:
    """An empty world saved by pybullet to `path`: its bytes, and where in them its solver
    info's iteration count (`m_numIterations`; the solver mode `m_solverMode` follows it)
    lies. pybullet cannot set the solver mode, but `loadBullet` copies a saved world's solver
    info into the world that loads it: a patched file sets it."""
    client = pb.connect(pb.DIRECT)
    try:
        pb.setPhysicsEngineParameter(numSolverIterations=_MARKER_ITERATIONS,
                                     physicsClientId=client)
        pb.saveBullet(str(path), physicsClientId=client)
    finally:
        pb.disconnect(client)
    data = bytearray(path.read_bytes())
    marker = struct.pack("<i", _MARKER_ITERATIONS)
    if data.count(marker) != 1:
        raise RuntimeError(f"{path}: the solver info's iteration count is not found once")
    return data, data.index(marker)


def solver_mode_world(folder: Path, flags: int) -> Path:
    """An empty world saved by pybullet, these flags added to its solver mode (0: as saved)."""
    path = folder / f"world-{flags}.bullet"
    data, iterations_at = saved_empty_world(path)
    at = iterations_at + 4
    (mode,) = struct.unpack_from("<i", data, at)
    struct.pack_into("<i", data, at, mode | flags)
    path.write_bytes(bytes(data))
    return path


@functools.cache
def _rigid_world_bytes() -> bytes:
    """The saved world a world of rigid boxes loads first: pybullet's solver mode plus
    `SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION`, made once per process."""
    with tempfile.TemporaryDirectory() as folder:
        flags = SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION
        return solver_mode_world(Path(folder), flags).read_bytes()


def load_saved_world(client: Any, path: Path) -> None:
    """Give a new world (its `BulletClient`) the solver info of a saved world, and pybullet's
    residual threshold back, which loading resets."""
    client.loadBullet(str(path))
    client.setPhysicsEngineParameter(solverResidualThreshold=_PYBULLET_RESIDUAL_THRESHOLD)


def _load_rigid_solver_mode(client: Any) -> None:
    """Give a new world the solver mode of `_rigid_world_bytes`, through a file of its own that
    is gone once loaded."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "world.bullet"
        path.write_bytes(_rigid_world_bytes())
        load_saved_world(client, path)


class _Client(bullet_client.BulletClient):
    """pybullet's client wrapper, safe to collect half-built: an interrupt (Ctrl-C, SIGTERM)
    inside its `__init__`, before it set `_client`, made its `__del__` look the attribute up in
    the pybullet module and print an ignored AttributeError with a traceback."""

    _client = -1


class BulletWorld:
    """Boxes in a Bullet world of their own (`BulletClient`, DIRECT), addressed by index.

    Use as a context manager or call `close()`: every world disconnects its client, so searches
    that build thousands of worlds do not leak them.
    """

    def __init__(self, timestep_s: float, solver_iterations: int,
                 contact_erp: float | None = None, rigid: bool = False) -> None:
        """`contact_erp`: the share of a penetration corrected per step (None: pybullet's).
        `rigid`: boxes are rigid (maximal-coordinate) bodies, not reduced-coordinate ones
        (`add_box`)."""
        self.rigid = rigid
        with _quiet_stdout():
            self._client: Any = _Client(connection_mode=pb.DIRECT)
            if rigid:
                _load_rigid_solver_mode(self._client)
        self.timestep_s = timestep_s
        # Per-step calls go to pybullet with this client's id: the same client, without the
        # BulletClient wrapper's attribute lookup (halves the cost of a state read or a step).
        self._id = self._client._client
        self._set_parameters(solver_iterations, contact_erp)
        self._ids: list[int] = []
        self._friction: dict[int, float] = {}
        #: a rigid body's inverse principal moments of inertia (1/(kg m²)), by Bullet id
        self._inverse_inertia: dict[int, np.ndarray] = {}
        self._anchor_wanted: dict[int, bool] = {}
        self._refreshing: set[int] = set()
        self._steps = 0  # steps taken, so `state` knows when a finite difference is exact
        #: (bodies, steps taken, positions, quaternions) of the last `state` call
        self._last_state: tuple[tuple[int, ...], int, np.ndarray, np.ndarray] | None = None

    def _set_parameters(self, solver_iterations: int, contact_erp: float | None) -> None:
        """The world's time step, solve and gravity (after a saved world's solver mode is
        loaded: benchmarks/bench_warm_start.py loads others)."""
        self._client.setTimeStep(self.timestep_s)
        self._client.setPhysicsEngineParameter(
            numSolverIterations=solver_iterations, deterministicOverlappingPairs=1
        )
        if contact_erp is not None:
            self._client.setPhysicsEngineParameter(contactERP=contact_erp)
        self._client.setGravity(0, 0, -G)

    # -- building -------------------------------------------------------------------------
    def add_box(
        self,
        size_m: Sequence[float],
        centre_m: Sequence[float],
        mass_kg: float,
        friction: float,
        rgba: Sequence[float] = (0.6, 0.6, 0.6, 1.0),
    ) -> int:
        """Add a box (mass 0: static, part of the sled). Returns its index in this world."""
        c = self._client
        friction = round(friction, FRICTION_DECIMALS)
        half = [s / 2 for s in size_m]
        col = c.createCollisionShape(pb.GEOM_BOX, halfExtents=half)
        vis = c.createVisualShape(pb.GEOM_BOX, halfExtents=half, rgbaColor=list(rgba))
        body = c.createMultiBody(mass_kg, col, vis, basePosition=list(centre_m),
                                 useMaximalCoordinates=self.rigid)
        c.changeDynamics(
            body, -1, lateralFriction=friction, restitution=0.0, rollingFriction=0.0,
            spinningFriction=0.0, linearDamping=0.0, angularDamping=0.0,
            activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING,
            # Friction anchors hold sticking contacts in place; without them a loaded pallet
            # creeps ~1 mm/s under static friction (measured: 14 mm in 10 s on a still sled).
            # Sliding contacts drop them (`set_anchored`): anchored slides run 4 % short.
            frictionAnchor=1,
        )
        self._friction[body] = friction
        if self.rigid and mass_kg > 0:
            inertia = c.getDynamicsInfo(body, -1)[2]
            self._inverse_inertia[body] = 1.0 / np.array(inertia)
        self._anchor_wanted[body] = True
        self._ids.append(body)
        return len(self._ids) - 1

    # -- stepping -------------------------------------------------------------------------
    def set_sled_accel(self, accel_mps2: float) -> None:
        """Apply the sled's acceleration as an inertial field for the next steps."""
        pb.setGravity(-accel_mps2, 0.0, -G, physicsClientId=self._id)

    def apply_wrenches(self, indices: Sequence[int] | np.ndarray, centres: np.ndarray,
                       forces: np.ndarray, torques: np.ndarray, rotations: np.ndarray) -> None:
        """Forces at the bodies' centres and torques (world frame) for the next step only.
        `rotations` (n, 3, 3): the bodies' orientations now, with which a rigid body takes its
        torque (`_turn`)."""
        cid = self._id
        forces, torques = forces.round(WRENCH_DECIMALS), torques.round(WRENCH_DECIMALS)
        for index, centre, force in zip(indices, centres.tolist(), forces.tolist(), strict=True):
            pb.applyExternalForce(self._ids[index], -1, force, centre, pb.WORLD_FRAME,
                                  physicsClientId=cid)
        if self.rigid:
            self._turn(indices, torques, rotations)
            return
        for index, torque in zip(indices, torques.tolist(), strict=True):
            pb.applyExternalTorque(self._ids[index], -1, torque, pb.WORLD_FRAME,
                                   physicsClientId=cid)

    def _turn(self, indices: Sequence[int] | np.ndarray, torques: np.ndarray,
              rotations: np.ndarray) -> None:
        """Torques on rigid bodies, given as the angular velocity they add in one step
        (w += dt I_world^-1 tau) before the step rather than as external torques.

        Bullet's rigid-body solver leaves an external torque out of the velocity its friction
        rows hold still (btSequentialImpulseConstraintSolver::setupFrictionConstraint adds the
        step's external force impulse but not its torque impulse, which only the normal rows
        see), so each step the torque turns a box that friction should hold by tau dt² / I: a
        box twisted below its friction limit creeps round at a steady rate
        (tests/wrapenv/test_bullet.py). As a velocity, friction sees it and holds it. The
        velocity added to is Bullet's own, read back, not the poses' finite difference, whose
        last bits depend on the processor (`FRICTION_DECIMALS`)."""
        cid = self._id
        bodies = [self._ids[i] for i in indices]
        if not bodies:
            return
        inverse = np.array([self._inverse_inertia[b] for b in bodies])
        in_body = np.einsum("nji,nj->ni", rotations, torques)  # R^T tau
        added = self.timestep_s * np.einsum("nij,nj->ni", rotations, inverse * in_body)
        for body, turn in zip(bodies, added.round(VELOCITY_DECIMALS).tolist(), strict=True):
            omega = pb.getBaseVelocity(body, physicsClientId=cid)[1]
            turned = [w + dw for w, dw in zip(omega, turn, strict=True)]
            pb.resetBaseVelocity(body, angularVelocity=turned, physicsClientId=cid)

    def push(self, index: int, force_n: Sequence[float]) -> None:
        """A force at the body's centre (world frame) for the next step only."""
        body = self._ids[index]
        centre = self._client.getBasePositionAndOrientation(body)[0]
        self._client.applyExternalForce(body, -1, list(force_n), centre, pb.WORLD_FRAME)

    def set_friction(self, index: int, coefficient: float) -> None:
        """Set a body's own coefficient; Bullet multiplies the two bodies' values per contact."""
        body = self._ids[index]
        coefficient = round(coefficient, FRICTION_DECIMALS)
        if self._friction[body] != coefficient:
            pb.changeDynamics(body, -1, lateralFriction=coefficient, physicsClientId=self._id)
            self._friction[body] = coefficient

    def set_anchored(self, index: int, anchored: bool) -> None:
        """Whether the body's contacts use friction anchors (wanted while they stick)."""
        body = self._ids[index]
        if self._anchor_wanted[body] != anchored:
            self._anchor_wanted[body] = anchored
            if body not in self._refreshing:
                pb.changeDynamics(body, -1, frictionAnchor=int(anchored),
                                  physicsClientId=self._id)

    def refresh_contacts(self, indices: Sequence[int]) -> None:
        """Make the bodies' contacts pick up changed friction coefficients in the next step.

        Bullet stores the combined coefficient in each contact point when the point is made, and
        with friction anchors it keeps a point for as long as its force stays inside the friction
        cone, so a new coefficient would never reach a persisting contact. Dropping the anchors
        for one step lets Bullet rebuild those points; `step` then restores what is wanted.
        """
        for index in indices:
            body = self._ids[index]
            if body not in self._refreshing:
                pb.changeDynamics(body, -1, frictionAnchor=0, physicsClientId=self._id)
                self._refreshing.add(body)

    def step(self) -> None:
        pb.stepSimulation(physicsClientId=self._id)
        self._steps += 1
        for body in self._refreshing:
            if self._anchor_wanted[body]:
                pb.changeDynamics(body, -1, frictionAnchor=1, physicsClientId=self._id)
        self._refreshing.clear()

    def stop(self, indices: Iterable[int]) -> None:
        """Set the bodies' velocities to zero: a unit that rested starts the next level still."""
        for index in indices:
            pb.resetBaseVelocity(self._ids[index], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0],
                                 physicsClientId=self._id)
        self._last_state = None

    # -- state ----------------------------------------------------------------------------
    def poses(self, indices: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Positions (n, 3) and quaternions (n, 4, x y z w) of the given bodies."""
        get, cid = pb.getBasePositionAndOrientation, self._id
        states = [get(self._ids[i], physicsClientId=cid) for i in indices]
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def state(self, indices: Sequence[int]) -> tuple[np.ndarray, ...]:
        """Positions (n, 3), quaternions (n, 4), linear and angular velocities (n, 3) of the
        given bodies, sled frame.

        Bullet moves a body's base by x += v dt and q = exp(w dt) q (world frame) with the
        velocities after the step, so one step after the previous call for the
        same bodies the velocities are the poses' finite differences, exact to 1e-14
        (tests/wrapenv/test_bench_health.py). That saves the second pybullet call per body, a
        state request of ~30 000 instructions, which was a fifth of a wrapped step's Python.
        """
        pos, quat = self.poses(indices)
        bodies, last = tuple(indices), self._last_state
        if last is not None and last[0] == bodies and last[1] == self._steps - 1:
            vel, omega = _step_velocities(last[2], last[3], pos, quat, self.timestep_s)
        else:
            vel, omega = self.velocities(indices)
        self._last_state = (bodies, self._steps, pos, quat)
        return pos, quat, vel, omega

    def velocities(self, indices: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """Linear (n, 3) and angular (n, 3) velocities of the given bodies (sled frame)."""
        get, cid = pb.getBaseVelocity, self._id
        states = [get(self._ids[i], physicsClientId=cid) for i in indices]
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def contact_points(self) -> int:
        """How many contact points Bullet holds now: its solver's work per iteration grows with
        them (benchmarks/bench_baseline.py)."""
        return len(pb.getContactPoints(physicsClientId=self._id))

    def max_penetration_m(self) -> float:
        """Deepest overlap between any two bodies now (0 when none overlaps)."""
        contacts = self._client.getContactPoints()
        if not contacts:
            return 0.0
        return max(0.0, -min(cp[8] for cp in contacts))

    # -- drawing --------------------------------------------------------------------------
    def set_pose(self, index: int, position_m: Sequence[float], quat: Sequence[float]) -> None:
        """Place a body at a recorded pose (quaternion x y z w): for drawing states, not for
        simulating (velocities are left as they are)."""
        self._last_state = None
        self._client.resetBasePositionAndOrientation(self._ids[index], list(position_m),
                                                     list(quat))

    def camera_image(
        self,
        width: int,
        height: int,
        view: Sequence[float],
        projection: Sequence[float],
    ) -> np.ndarray:
        """RGB image (height, width, 3) uint8 from TinyRenderer, the CPU renderer that works
        headless in DIRECT mode. `view` and `projection` are OpenGL 4x4 matrices, column-major.

        Shadows are off: TinyRenderer computes them with the camera's own projection, which is
        wrong for anything but a perspective camera; no specular highlight either, so a face's
        colour depends only on its orientation (steady colours for trackers).
        """
        rgb, _ = self._render(width, height, view, projection, False)
        return rgb

    def camera_image_and_mask(
        self,
        width: int,
        height: int,
        view: Sequence[float],
        projection: Sequence[float],
    ) -> tuple[np.ndarray, np.ndarray]:
        """`camera_image` and, per pixel, the index in this world of the body seen there (-1:
        none): which pixels a texture of that body may paint."""
        rgb, seg = self._render(width, height, view, projection, True)
        lookup = np.full(max(self._ids) + 2, -1, np.int32)  # unique id -> index; id -1 -> -1
        lookup[np.array(self._ids)] = np.arange(len(self._ids))
        return rgb, lookup[np.asarray(seg, np.int64).reshape(height, width)]

    def _render(self, width: int, height: int, view: Sequence[float],
                projection: Sequence[float], mask: bool) -> tuple[np.ndarray, np.ndarray | None]:
        _, _, rgba, _, seg = self._client.getCameraImage(
            width, height, viewMatrix=[float(v) for v in view],
            projectionMatrix=[float(p) for p in projection], renderer=pb.ER_TINY_RENDERER,
            shadow=0, lightDirection=list(LIGHT_DIRECTION), lightAmbientCoeff=LIGHT_AMBIENT,
            lightDiffuseCoeff=LIGHT_DIFFUSE, lightSpecularCoeff=0.0,
            flags=0 if mask else pb.ER_NO_SEGMENTATION_MASK,
        )
        rgb = np.asarray(rgba, np.uint8).reshape(height, width, 4)[..., :3].copy()
        return rgb, (seg if mask else None)

    # -- lifetime -------------------------------------------------------------------------
    @property
    def closed(self) -> bool:
        """True once the client is disconnected."""
        return self._client is None

    def close(self) -> None:
        """Disconnect the client; safe to call more than once."""
        if self._client is not None:
            with contextlib.suppress(pb.error):
                self._client.disconnect()
            self._client = None

    def __enter__(self) -> BulletWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()

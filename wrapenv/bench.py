"""The virtual ESTL bench: run a load unit through one test level or the EUMOS sequence."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from wrapenv.bullet import BulletWorld, G
from wrapenv.eumos import LevelVerdict, Verdict, evaluate
from wrapenv.friction import WRAPPED_SLIP_SPEED_MPS, WRAPPED_STICK_SPEED_MPS, StickSlip
from wrapenv.load import Layout, LoadUnit
from wrapenv.profile import Profile, PulseProfile
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet

SLED_MARGIN_M = 2.0          # sled deck beyond the pallet on every side
SLED_DECK_M = 0.1            # thickness of the sled deck (its top is z = 0)
STOPPER_SIZE_M = (0.05, 0.08)  # pallet stopper bar: thickness along x, height
PENETRATION_LIMIT_M = 0.02   # deeper overlap than this means the solver lost the contact


@dataclass(frozen=True)
class SimSettings:
    """Numerical settings of the bench. The defaults pass the closed-form tests
    (tests/wrapenv/test_bench_mechanics.py) and are the ones the benchmarks report."""

    timestep_s: float = 1 / 240
    solver_iterations: int = 20
    #: Contact states are updated and poses recorded every `sample_every` steps.
    sample_every: int = 1
    settle_s: float = 0.3
    #: The run ends once every body is slower than this (relative to the sled) for `rest_hold_s`
    #: after the sled stopped, or `max_rest_wait_s` after it stopped at the latest.
    rest_speed_mps: float = 0.005
    rest_hold_s: float = 0.2
    max_rest_wait_s: float = 3.0


@dataclass(frozen=True)
class Push:
    """A constant horizontal force on one bundle while the sled runs its profile: the lateral
    push with which a wrap's hold on a layer is measured (tests, containment checks)."""

    bundle: str
    force_n: tuple[float, float]


@dataclass(frozen=True)
class BenchRun:
    verdict: Verdict
    traces: tuple[Trace, ...]


def run_level(layout: Layout, profile: Profile, settings: SimSettings = SimSettings(),
              wrap: WrapFormat | None = None, push: Push | None = None) -> Trace:
    """Simulate one pulse on a freshly stacked (and wrapped) unit until everything rests."""
    with BulletWorld(settings.timestep_s, settings.solver_iterations) as world:
        stick_slip = (StickSlip(layout) if wrap is None else
                      StickSlip(layout, WRAPPED_SLIP_SPEED_MPS, WRAPPED_STICK_SPEED_MPS))
        _build(world, layout, stick_slip.coefficients())
        net = WrapNet(wrap, layout) if wrap is not None else None
        return _Run(world, layout, profile, settings, stick_slip, net, push).execute()


def run_levels(
    load: LoadUnit,
    levels: Iterable[float | Profile],
    settings: SimSettings = SimSettings(),
    orientation: str | None = None,
    stop_at_failure: bool = False,
    wrap: WrapFormat | None = None,
) -> BenchRun:
    """Run test levels (in g, or explicit profiles) on fresh copies of the unit."""
    layout = load.layout(orientation)  # type: ignore[arg-type]
    verdicts: list[LevelVerdict] = []
    traces: list[Trace] = []
    for level in levels:
        profile = PulseProfile(level) if isinstance(level, int | float) else level
        trace = run_level(layout, profile, settings, wrap)
        verdict = evaluate(trace)
        traces.append(trace)
        verdicts.append(verdict)
        if stop_at_failure and not verdict.passed:
            break
    return BenchRun(Verdict(layout.load_height_m, tuple(verdicts)), tuple(traces))


def _build(world: BulletWorld, layout: Layout, mu: np.ndarray) -> None:
    """Add sled (index 0), pallet (1) and bundles (2 + k) in the order `StickSlip` numbers them."""
    px, py, pz = layout.pallet_size_m
    deck = (px + 2 * SLED_MARGIN_M, py + 2 * SLED_MARGIN_M, SLED_DECK_M)
    world.add_box(deck, (0, 0, -SLED_DECK_M / 2), 0.0, mu[0], rgba=(0.35, 0.35, 0.4, 1))
    world.add_box((px, py, pz), (0, 0, pz / 2), layout.pallet_mass_kg, mu[1],
                  rgba=(0.76, 0.6, 0.4, 1))
    for k, b in enumerate(layout.bundles):
        # a hair above the layer below, so nothing starts overlapping; settling closes it
        z = b.centre_m[2] + 1e-4 * b.layer
        world.add_box(b.size_m, (b.centre_m[0], b.centre_m[1], z), b.mass_kg, mu[2 + k],
                      rgba=(0.2, 0.45, 0.8, 1))
    if layout.pallet_stopper:
        t, h = STOPPER_SIZE_M
        world.add_box((t, py, h), (-px / 2 - t / 2 - 1e-3, 0, h / 2), 0.0, mu[0],
                      rgba=(0.2, 0.2, 0.2, 1))


def _rotations(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) from quaternions (n, 4) in Bullet's x y z w order."""
    x, y, z, w = quat.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


class _Run:
    """The stepping loop of one level: inertial field, contact states, records, health checks."""

    def __init__(self, world: BulletWorld, layout: Layout, profile: Profile,
                 settings: SimSettings, stick_slip: StickSlip, wrap: WrapNet | None,
                 push: Push | None) -> None:
        self.world, self.layout, self.profile, self.s = world, layout, profile, settings
        self.stick_slip, self.wrap = stick_slip, wrap
        self.push = None
        if push is not None:
            names = [b.name for b in layout.bundles]
            if push.bundle not in names:
                raise ValueError(f"no bundle {push.bundle!r} to push")
            self.push = (2 + names.index(push.bundle), (*push.force_n, 0.0))
        self.n_bodies = stick_slip.n_bodies
        self.dynamic = list(range(1, self.n_bodies))  # pallet and bundles
        n_steps = int(np.ceil((profile.duration_s + settings.max_rest_wait_s)
                              / settings.timestep_s)) + 2
        # The sled's acceleration at every step, evaluated once instead of inside the step loop.
        self.accel = profile.accel(np.arange(n_steps) * settings.timestep_s)
        dv = np.cumsum(self.accel) * settings.timestep_s
        # No body can move relative to the sled faster than the sled's change of speed plus the
        # speed of a fall from the top of the load: beyond that energy came from nowhere.
        self.speed_limit = float(np.max(np.abs(dv))) + math.sqrt(2 * G * layout.load_height_m) + 1.0
        self.samples: list[tuple[float, float, np.ndarray, np.ndarray]] = []
        self.invalid = ""

    def _state(self) -> tuple[np.ndarray, ...]:
        pos, quat = self.world.poses(self.dynamic)
        vel, omega = self.world.velocities(self.dynamic)
        return pos, quat, vel, omega

    def _update_friction(self, pos, rot, vel, omega) -> None:
        zeros = np.zeros((1, 3))
        full = (np.vstack([zeros, pos]), np.concatenate([np.eye(3)[None], rot]),
                np.vstack([zeros, vel]), np.vstack([zeros, omega]))
        changed = self.stick_slip.update(*full)
        if not changed:
            return
        mu = self.stick_slip.coefficients()
        for index, value in enumerate(mu):
            self.world.set_friction(index, float(value))
        if self.layout.pallet_stopper:
            self.world.set_friction(self.n_bodies, float(mu[0]))  # the stopper is sled
        sliding = self.stick_slip.sliding_bodies()
        for index in range(self.n_bodies):
            self.world.set_anchored(index, index not in sliding)
        self.world.refresh_contacts(changed)

    def _check(self, pos: np.ndarray, vel: np.ndarray, step: int) -> None:
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            self.invalid = "non-finite state"
        elif np.max(np.linalg.norm(vel, axis=1)) > self.speed_limit:
            self.invalid = f"a body exceeded {self.speed_limit:.1f} m/s (energy blow-up)"
        elif step % 24 == 0:
            depth = self.world.max_penetration_m()
            if depth > PENETRATION_LIMIT_M:
                self.invalid = f"bodies interpenetrate by {depth * 1000:.0f} mm"

    def _apply_wrap(self, pos, rot, vel, omega, t_s: float | None = None) -> None:
        force, torque = self.wrap.forces(pos, rot, vel, omega, t_s)  # type: ignore[union-attr]
        bodies = np.flatnonzero(np.any(force != 0, axis=1) | np.any(torque != 0, axis=1))
        # state index j is world index j + 1 (the sled is 0)
        self.world.apply_wrenches(bodies + 1, pos[bodies], force[bodies], torque[bodies])

    def _settle(self) -> None:
        """Let the stack settle on the still sled; a wrap is laid at its wrapping tension,
        rising smoothly over the first two thirds of the settling time."""
        self.world.set_sled_accel(0.0)
        n = round(self.s.settle_s / self.s.timestep_s)
        for step in range(n):
            if self.wrap is not None:
                x = min(1.0, step / (2 * n / 3))
                self.wrap.laying(x * x * (3 - 2 * x))
                pos, quat, vel, omega = self._state()
                self._apply_wrap(pos, _rotations(quat), vel, omega)
            self.world.step()
        if self.wrap is not None:
            pos, quat, _, _ = self._state()
            self.wrap.freeze(pos, _rotations(quat))

    def execute(self) -> Trace:
        s, world = self.s, self.world
        dt = s.timestep_s
        self._settle()
        step, t, rest_since = 0, 0.0, None
        end_cap = self.profile.duration_s + s.max_rest_wait_s
        while True:
            sample = step % s.sample_every == 0
            if sample or self.wrap is not None:
                pos, quat, vel, omega = self._state()
                rot = _rotations(quat)
            if self.wrap is not None:
                self._apply_wrap(pos, rot, vel, omega, t)
            if self.push is not None and t < self.profile.duration_s:
                world.push(self.push[0], self.push[1])
            if sample:
                self.samples.append((t, float(self.accel[step]), pos, rot))
                self._check(pos, vel, step)
                if self.invalid:
                    break
                self._update_friction(pos, rot, vel, omega)
                if t >= self.profile.duration_s:
                    still = (np.max(np.linalg.norm(vel, axis=1)) < s.rest_speed_mps
                             and np.max(np.linalg.norm(omega, axis=1)) < 10 * s.rest_speed_mps)
                    rest_since = (rest_since if rest_since is not None else t) if still else None
                    if (rest_since is not None and t - rest_since >= s.rest_hold_s) or t >= end_cap:
                        break
            world.set_sled_accel(float(self.accel[step + 1]))
            world.step()
            step += 1
            t = step * dt
        return self._trace()

    def _trace(self) -> Trace:
        t, a, pos, rot = zip(*self.samples, strict=True)
        pos_arr, rot_arr = np.array(pos), np.array(rot)
        return Trace(
            level_g=self.profile.level_g,
            load_height_m=self.layout.load_height_m,
            names=tuple(b.name for b in self.layout.bundles),
            bottom_z_m=np.array([b.centre_m[2] - b.size_m[2] / 2 for b in self.layout.bundles]),
            t_s=np.array(t),
            sled_accel_mps2=np.array(a),
            pallet_pos=pos_arr[:, 0],
            pallet_rot=rot_arr[:, 0],
            bundle_pos=pos_arr[:, 1:],
            bundle_rot=rot_arr[:, 1:],
            valid=not self.invalid,
            invalid_reason=self.invalid,
            wrap=self.wrap.report() if self.wrap is not None else None,
        )

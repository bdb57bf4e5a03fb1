"""The virtual ESTL bench: run a load unit through one test level or the EUMOS sequence."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np

from wrapenv.bullet import BulletWorld, rotation_matrices
from wrapenv.config import InputError, is_finite_number, is_whole_number
from wrapenv.eumos import (
    ELASTIC,
    EUMOS_LIMITS,
    WRAP_TORN,
    LevelVerdict,
    Limits,
    Verdict,
    evaluate,
    fallen,
)
from wrapenv.friction import WRAPPED_SLIP_SPEED_MPS, WRAPPED_STICK_SPEED_MPS, StickSlip
from wrapenv.load import Layout, LoadUnit, Orientation
from wrapenv.profile import G, Profile, PulseProfile
from wrapenv.rest import Rest
from wrapenv.rowwise import norms
from wrapenv.scene import BUNDLES, PALLET, SLED_DECK_M, BenchScene
from wrapenv.trace import Trace, in_pallet_frame
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet

#: Deeper overlap than this, kept for `PENETRATION_HOLD_S`, means the solver lost the contact.
PENETRATION_LIMIT_M = 0.02
#: How long an overlap may stay past the limit: an impact drives a body in for a few steps.
#: A bundle falling off the 3-layer example is driven up to 22 mm into the deck (32 mm from a
#: film that gives way), and the solver pushes it back within the limit in 2 steps (10, at
#: the wrapped contact ERP): docs/bench.md, "An impact is not a lost contact". Judged on the
#: overlap of one step, such a fall made a level invalid or not by whether the depth, read
#: every `PENETRATION_READ_STEPS`, fell on the impact's step.
PENETRATION_HOLD_S = 0.1
#: The depth, a query over every contact, is read every this many steps, and every step while
#: an overlap stands past the limit.
PENETRATION_READ_STEPS = 24


@dataclass(frozen=True)
class SimSettings:
    """Numerical settings of the bench. The defaults pass the closed-form tests
    (tests/wrapenv/test_bench_mechanics.py) and are the ones the benchmarks report."""

    timestep_s: float = 1 / 240
    #: Every unit's solve. At 20 a stack is left unconverged: it creeps a few mm/s under static
    #: friction. Wrapped, the wrap's squeeze makes that a creep of the whole stack (the
    #: machine's default Kraft program on the 3-layer example: 15-25 mm at 0.2 g, then failed;
    #: with 50 it passes every level to 0.8 g, as with 100). Unwrapped, the creep of a bundle
    #: on a bundle past the stick speed flips its contact to sliding below its static friction
    #: (a column of two PET bundles slid 43 mm at 0.25 g on static 0.28; at 50 and 100 it
    #: holds: benchmarks/stacked_static.py). A stack that does not creep also comes to rest, so
    #: a wrapped level ends sooner: a wrapped sequence takes less CPU at 50 than at 20
    #: (benchmarks/bench_solver.py); an unwrapped one takes 1.3-2.1 x as much.
    solver_iterations: int = 50
    #: A squeeze harder still (ten top wraps where the Kraft default lays three, all at its
    #: 800 N) leaves 50 iterations unconverged too: on the 2-layer example the stack crept 6.9 mm
    #: at 0.2 g and was still moving 3 s after the sled stopped, so more wrap looked worse than
    #: less; with 100 it rests at 0.5 mm, and in a fifth of the CPU. At training's 1/160 s
    #: step such squeezes also leave bodies inside each other or blow up at 50, not at 100
    #: (benchmarks/training_invalid.py). So a wrapped sequence whose squeeze a level shows
    #: unsolved (`unconverged`) is run again from the start with twice the iterations, up to
    #: this many (`run_levels`; benchmarks/bench_solver.py).
    max_solver_iterations: int = 200
    #: A wrapped unit's contact ERP, the share of a penetration Bullet corrects per step
    #: (pybullet's default: 0.08). Converged under a squeeze of many times the bundles' weight,
    #: that correction kicks squeezed bodies apart: the search space's heaviest Kraft program
    #: on a two-bundle unit blew up at 0.3 g (36 mm overlap) with 0.08, not with 0.05, which
    #: moves the wrapped examples' figures by about a millimetre (benchmarks/bench_solver.py).
    wrapped_contact_erp: float = 0.05
    settle_s: float = 0.3
    #: The run ends once no body has moved (relative to the sled) faster than this on average,
    #: i.e. by more than rest_speed_mps x rest_hold_s (0.5 mm), for `rest_hold_s` after the
    #: sled stopped, or `max_rest_wait_s` after it stopped at the latest (then the trace says
    #: so, `Trace.not_at_rest`). A 0.1 s hold ends runs within 0.6 mm of a 0.2 s one (10
    #: wrapped and unwrapped cases, every step simulated).
    rest_speed_mps: float = 0.005
    rest_hold_s: float = 0.1
    max_rest_wait_s: float = 3.0
    #: Skip what cannot change: while the sled's acceleration stays constant and too low to
    #: slide or tip anything, a unit that rests stays as it is, so the run records the rest and
    #: jumps to the next change of acceleration (wrapenv/rest.py gives the argument).
    #: Off: every step is simulated (the tests that check the skip compare both).
    skip_still: bool = True
    #: End a level as soon as its verdict is decided failed (a bundle fallen, the wrap torn,
    #: elastic displacement past its limit), for searches and training; the trace then ends
    #: there and says why (`Trace.stopped_early`). Off: every level runs to rest, as `simulate`
    #: and reports need it (but for a body gone over the edge of the sled's deck: `_Run`).
    stop_when_decided: bool = False
    #: After a rest in the quiet deceleration, simulate the sled's stop (the deceleration let
    #: go) and end at the rest after it. Off: end at the first rest, as if the stop changed
    #: nothing, which saves a rest hold: for screening. A wrapped unit springs back at the stop
    #: by up to ~1 mm (14 cases, benchmarks/bench_screening.py).
    simulate_stop: bool = True
    #: Boxes as rigid (maximal-coordinate) bodies instead of reduced-coordinate ones. Bullet
    #: warm-starts their contacts: a Kraft-wrapped 3-layer level takes half the CPU, 0.93 x
    #: the issue's plain PyBullet run (benchmarks/bench_baseline.py). Off by default: their
    #: friction is a pyramid on two world-fixed directions, not a cone (a box pulled at 22.5
    #: degrees to x slides along x; benchmarks/bench_rigid.py). Wrapped margins stand 0.20 from
    #: the default's on average, about as far as the bench's own from itself renumbered
    #: (benchmarks/bench_screening.py, bench_reflection.py); the closed-form tests pass either way.
    rigid_boxes: bool = False

    def __post_init__(self) -> None:
        """Settings a run can be made with; a negative step or NaN wait ran on silently, and
        no run of it means anything."""
        for name in ("timestep_s", "rest_speed_mps", "rest_hold_s"):
            if not (is_finite_number(value := getattr(self, name)) and value > 0):
                raise InputError("settings", name, f"must be a number > 0 (got {value!r})")
        for name in ("settle_s", "max_rest_wait_s"):   # 0: a replay waits for no rest
            if not (is_finite_number(value := getattr(self, name)) and value >= 0):
                raise InputError("settings", name, f"must be a number >= 0 (got {value!r})")
        for name in ("solver_iterations", "max_solver_iterations"):
            if not (is_whole_number(value := getattr(self, name)) and value >= 1):
                raise InputError("settings", name, f"must be a whole number >= 1 (got {value!r})")
        if not (is_finite_number(self.wrapped_contact_erp) and 0 < self.wrapped_contact_erp <= 1):
            raise InputError("settings", "wrapped_contact_erp",
                             f"must be in (0, 1] (got {self.wrapped_contact_erp!r})")

    @classmethod
    def screening(cls) -> SimSettings:
        """A cheaper fidelity to screen candidates with in a search, confirming the best with
        the defaults: a level ends at its first rest in the deceleration and as soon as it has
        failed. Numerically cheaper settings (a larger step, fewer solver iterations) move a
        wrapped unit's margin by 0.2 on average and keep a squeezed stack from resting;
        agreement and speed-up of each: benchmarks/bench_screening.py."""
        return cls(simulate_stop=False, stop_when_decided=True)

    @classmethod
    def training(cls) -> SimSettings:
        """The screening fidelity at a 1.5 x longer step and a rest held half as long, for
        PPO's training envs. It misses a margin by about as much as the bench's own ordering of
        contacts does (about 0.15: benchmarks/bench_reflection.py), which a search could not
        accept of a screened failure but a reward can: a reward is one draw anyway, and a
        policy's proposal is verified at the defaults. (A shorter settling, a quarter of a
        trained policy's episode, laid the wrap with a jolt: a two-bundle unit's margin 0.17
        lower at 0.2 s, 0.37 at 0.15 s; settled at a 2 x longer step, it failed at 0.3 g:
        docs/speed.md.) Agreement and speed-up on random units and on the screening cases:
        benchmarks/bench_train.py, benchmarks/bench_screening.py."""
        return replace(cls.screening(), timestep_s=1 / 160, rest_hold_s=0.05)


@dataclass(frozen=True)
class Push:
    """A constant horizontal force on one bundle while the sled runs its profile: the lateral
    push with which a wrap's hold on a layer is measured (tests/wrapenv/test_wrap_physics.py:
    pretension squeezes a layer so that it resists a larger push)."""

    bundle: str
    force_n: tuple[float, float]


@dataclass(frozen=True)
class BenchRun:
    verdict: Verdict
    traces: tuple[Trace, ...]
    #: The solver iterations the run was made with (more than the settings' when a wrapped
    #: stack's solve did not converge: `run_levels`).
    solver_iterations: int
    #: The runs made before it, each as its iterations and what showed its squeezed stack
    #: unsolved (`unconverged`; none: the first run is the answer).
    unsolved_at: tuple[tuple[int, str], ...] = ()


def run_level(layout: Layout, profile: Profile, settings: SimSettings = SimSettings(),
              wrap: WrapFormat | None = None, push: Push | None = None) -> Trace:
    """Simulate one pulse on a freshly stacked (and wrapped) unit until everything rests."""
    with BenchUnit(layout, settings, wrap) as unit:
        return unit.level(profile, push)


class BenchUnit:
    """One unit on the sled through the levels a lab runs on it, stacked and wrapped once:
    each level starts where the last left it, every body at rest (velocities zero), the wrap's
    rest lengths, plastic stretch, tears and seam as they were (its peaks start again: its
    report is per level), the sled still, every contact sticking. The world is kept, so the
    resting stack's contacts carry too: in a world rebuilt at the same poses a 3-layer stack
    jolted by 1.5 mm at 0.05 g; kept, 0.01 mm (a fresh unit: 0.03 mm). A context manager (or
    `close()`)."""

    def __init__(self, layout: Layout, settings: SimSettings = SimSettings(),
                 wrap: WrapFormat | None = None) -> None:
        self.layout, self.settings, self.wrapped = layout, settings, wrap is not None
        self.scene = BenchScene(layout)
        erp = settings.wrapped_contact_erp if wrap is not None else None
        self.world = BulletWorld(settings.timestep_s, settings.solver_iterations, erp,
                                 settings.rigid_boxes)
        speeds = (WRAPPED_SLIP_SPEED_MPS, WRAPPED_STICK_SPEED_MPS) if self.wrapped else ()
        #: The contact states, kept with the world: they say which contacts a level's start
        #: must rebuild.
        self.stick_slip = StickSlip(self.scene, *speeds)
        try:
            _build(self.world, self.scene, self.stick_slip.coefficients())
            #: The wrap as the last level left it (None: unwrapped).
            self.wrap = WrapNet(wrap, layout) if wrap is not None else None
        except BaseException:  # an interrupt or bad wrap while building: no client left behind
            self.world.close()
            raise
        #: Bundle centres in the pallet frame when the unit was put on (None: before level 1).
        self.origin_m: np.ndarray | None = None

    def level(self, profile: Profile, push: Push | None = None,
              max_rest_wait_s: float | None = None) -> Trace:
        """Run one level on the unit as it stands: settled and wrapped first if it is new.
        `max_rest_wait_s` replaces the unit's settings' for this level (a replay of a recording
        ends where the recording's compared frames do, the levels before it at rest).

        A later level starts with every body still, so every contact sticks; only the contacts
        that slid when the last level ended are rebuilt. Rebuilding them all let the pallet's
        grip on the sled give: 1.9 mm of slip at 0.3 g in each level after the first
        (tests/wrapenv/test_sequence.py)."""
        settings = (self.settings if max_rest_wait_s is None
                    else replace(self.settings, max_rest_wait_s=max_rest_wait_s))
        new = self.origin_m is None
        if not new:
            self.world.stop(self.scene.moving.tolist())
            _set_friction(self.world, self.scene, self.stick_slip, self.stick_slip.stick_all())
            if self.wrap is not None:
                self.wrap.next_level()
        run = _Run(self.world, self.layout, profile, settings, self.stick_slip, self.wrap,
                   push, self.origin_m)
        trace = run.execute(settle=new)
        self.origin_m = trace.origin()
        return trace

    def close(self) -> None:
        self.world.close()

    def __enter__(self) -> BenchUnit:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run_levels(
    load: LoadUnit,
    levels: Iterable[float | Profile],
    settings: SimSettings = SimSettings(),
    orientation: Orientation | None = None,
    stop_at_failure: bool = False,
    wrap: WrapFormat | None = None,
    fresh: bool = False,
    limits: Limits = EUMOS_LIMITS,
    on_level: Callable[[LevelVerdict], None] | None = None,
    on_rerun: Callable[[int], None] | None = None,
) -> BenchRun:
    """Run test levels (in g, or explicit profiles) as a lab does: one unit, each level
    starting from the state the last one left (`fresh`: a freshly stacked and wrapped unit per
    level). A cumulative sequence ends after a level that left no state to go on from (invalid,
    or stopped once decided); a level still moving at the longest wait is judged where it
    stands, and the next starts from there.
    `on_level` hears each level's verdict as it is decided (progress for people).
    A wrapped sequence whose squeezed stack the solver did not converge (`unconverged`) is run
    again with twice the solver iterations, up to `SimSettings.max_solver_iterations`;
    `BenchRun.solver_iterations` says how many the answer took; `on_rerun` hears of a run
    started again, with its iterations."""
    levels = tuple(levels)
    unsolved: tuple[tuple[int, str], ...] = ()
    while True:
        run = _run_levels_once(load, levels, settings, orientation, stop_at_failure, wrap,
                               fresh, limits, on_level)
        why = unconverged(run) if wrap is not None else ""
        doubled = 2 * settings.solver_iterations
        if not why or doubled > settings.max_solver_iterations:
            return replace(run, unsolved_at=unsolved)
        unsolved += ((settings.solver_iterations, why),)
        settings = replace(settings, solver_iterations=doubled)
        if on_rerun is not None:
            on_rerun(doubled)


def unconverged(run: BenchRun) -> str:
    """What shows that a run's squeezed stack was not solved at its iterations ("" if
    nothing): a level made invalid by the solver (bodies left inside each other past the
    limit, or an energy blow-up: at 1/160 s heavy Kraft programs do both at 50 iterations,
    not at 100), or, in a valid run, a level that ended still moving though nothing broke,
    fell or tore (the stack crept on under static friction). A unit that came apart is no
    unsolved squeeze."""
    for trace in run.traces:
        if trace.unsolved:
            return trace.unsolved
    if run.verdict.valid and any(level.not_at_rest and not level.damage
                                 for level in run.verdict.levels):
        return "crept on under static friction"
    return ""


def _run_levels_once(
    load: LoadUnit,
    levels: Iterable[float | Profile],
    settings: SimSettings,
    orientation: Orientation | None,
    stop_at_failure: bool,
    wrap: WrapFormat | None,
    fresh: bool,
    limits: Limits,
    on_level: Callable[[LevelVerdict], None] | None,
) -> BenchRun:
    layout = load.layout(orientation)
    verdicts: list[LevelVerdict] = []
    traces: list[Trace] = []
    with contextlib.ExitStack() as stack:
        unit = None if fresh else stack.enter_context(BenchUnit(layout, settings, wrap))
        for level in levels:
            profile = PulseProfile(level) if isinstance(level, int | float) else level
            trace = (run_level(layout, profile, settings, wrap) if unit is None
                     else unit.level(profile))
            verdict = evaluate(trace, limits=limits)
            traces.append(trace)
            verdicts.append(verdict)
            if on_level is not None:
                on_level(verdict)
            if stop_at_failure and not verdict.passed:
                break
            if unit is not None and (not trace.valid or trace.stopped_early):
                break
    sequence = "fresh" if fresh else "cumulative"
    return BenchRun(Verdict(layout.load_height_m, tuple(verdicts), sequence), tuple(traces),
                    settings.solver_iterations)


def _build(world: BulletWorld, scene: BenchScene, mu: np.ndarray) -> None:
    """Add the scene's bodies with the body coefficients `mu` (indexed by `BenchScene.parts`)."""
    for body, part in zip(scene.bodies, scene.parts.tolist(), strict=True):
        world.add_box(body.size_m, body.start_centre_m, body.mass_kg, mu[part], rgba=body.rgba)


def _set_friction(world: BulletWorld, scene: BenchScene, stick_slip: StickSlip,
                  changed: Iterable[int]) -> None:
    """Give the world the body coefficients and friction anchors of the contact states, and
    make the contacts of the `changed` bodies pick them up."""
    mu = stick_slip.coefficients()
    for index, part in enumerate(scene.parts.tolist()):
        world.set_friction(index, float(mu[part]))
    sliding = stick_slip.sliding_bodies()
    for index in range(scene.n_parts):
        world.set_anchored(index, index not in sliding)
    world.refresh_contacts(list(changed))


class _Run:
    """The stepping loop of one level: inertial field, contact states, records, health checks."""

    def __init__(self, world: BulletWorld, layout: Layout, profile: Profile,
                 settings: SimSettings, stick_slip: StickSlip, wrap: WrapNet | None,
                 push: Push | None, origin_m: np.ndarray | None = None) -> None:
        self.world, self.layout, self.profile, self.s = world, layout, profile, settings
        self.stick_slip, self.wrap = stick_slip, wrap
        self.scene = stick_slip.scene
        self.push = None
        if push is not None:
            if push.bundle not in {b.name for b in layout.bundles}:
                raise ValueError(f"no bundle {push.bundle!r} to push")
            self.push = (self.scene.index(push.bundle), (*push.force_n, 0.0))
        self.dynamic = self.scene.moving.tolist()  # world indices of the state rows
        dt = settings.timestep_s
        n_steps = int(np.ceil((profile.duration_s + settings.max_rest_wait_s) / dt)) + 2
        # The sled's acceleration at every step, evaluated once instead of inside the step loop.
        self.accel = profile.accel(np.arange(n_steps) * dt)
        dv = np.cumsum(self.accel) * dt
        # No body can move relative to the sled faster than the sled's change of speed plus the
        # speed of a fall from the top of the load: beyond that energy came from nowhere.
        self.speed_limit = float(np.max(np.abs(dv))) + math.sqrt(2 * G * layout.load_height_m) + 1.0
        #: The first step at which the sled has stopped (the run may end from there on).
        self.stop_step = int(np.argmax(np.arange(n_steps) * dt >= profile.duration_s))
        self.rest = Rest(layout, self.accel, settings.rest_speed_mps * settings.rest_hold_s,
                         self.stop_step if push else None)
        self.samples: list[tuple[float, float, np.ndarray, np.ndarray]] = []
        self.invalid = ""
        #: The step since which an overlap has stood past `PENETRATION_LIMIT_M` (None: none),
        #: and the depth last read.
        self.deep_since: int | None = None
        self.depth_m = 0.0
        self.unsolved = ""  # what showed the solver failed, when that made the level invalid
        self.stopped_early = ""
        self.not_at_rest = ""
        #: Whether this level began with the unit stacked (and wrapped) on the still sled.
        self.settled = False
        self.reference: np.ndarray | None = None  # bundle centres in the pallet frame at t = 0
        self.origin_m = origin_m  # ... when the unit was first put on the sled (None: t = 0)
        self.bottom_z = np.array([b.centre_m[2] - b.size_m[2] / 2 for b in layout.bundles])
        self.elastic_limit_m = ELASTIC.limit_m(layout.load_height_m)

    def _state(self) -> tuple[np.ndarray, ...]:
        pos, quat, vel, omega = self.world.state(self.dynamic)
        return pos, rotation_matrices(quat), vel, omega

    def _update_friction(self, pos: np.ndarray, rot: np.ndarray, vel: np.ndarray,
                         omega: np.ndarray) -> None:
        changed = self.stick_slip.update_moving(pos, rot, vel, omega)
        if changed:
            _set_friction(self.world, self.scene, self.stick_slip, changed)

    def _check(self, pos: np.ndarray, vel: np.ndarray, step: int) -> None:
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            self.invalid = "non-finite state"
        elif np.max(norms(vel)) > self.speed_limit:
            self.invalid = f"a body exceeded {self.speed_limit:.1f} m/s (energy blow-up)"
            self.unsolved = "blew up"
        elif step % PENETRATION_READ_STEPS == 0 or self.deep_since is not None:
            self._check_overlap(step)

    def _check_overlap(self, step: int) -> None:
        """Invalid once bodies have stood deeper in each other than the limit for
        `PENETRATION_HOLD_S`: the solver did not push them out, as it does after an impact."""
        self.depth_m = self.world.max_penetration_m()
        if self.depth_m <= PENETRATION_LIMIT_M:
            self.deep_since = None
        elif self.deep_since is None:
            self.deep_since = step
        elif (step - self.deep_since) * self.s.timestep_s >= PENETRATION_HOLD_S - 1e-9:
            self.invalid = (f"bodies interpenetrate by {self.depth_m * 1000:.0f} mm "
                            f"for {PENETRATION_HOLD_S:g} s")
            self.unsolved = "left bodies inside each other"

    def _came_apart(self, pos: np.ndarray) -> str:
        """Which body moved farther than the pallet is long from where it was stacked while
        the unit settled and was wrapped ("" if none). A wrap closes the gaps of a unit stacked
        with them (tens of millimetres); nothing real flings a bundle off its pallet before the
        sled moves, so such a level is no test (it used to be judged from where the bundles
        landed: with 1 g bundles a valid failure, every one fallen at t = 0)."""
        bodies = [self.scene.bodies[w] for w in self.dynamic]
        stacked = np.array([b.start_centre_m for b in bodies])
        moved = np.linalg.norm(pos - stacked, axis=1)
        worst = int(np.argmax(moved))
        if moved[worst] <= max(self.layout.pallet_size_m[:2]):
            return ""
        return (f"the unit came apart before the sled moved ({bodies[worst].name} moved "
                f"{1000 * moved[worst]:.0f} mm while it was stacked and wrapped)")

    def _off_the_sled(self, pos: np.ndarray) -> str:
        """Which body has gone over the edge of the sled's deck ("" if none): its centre below
        the deck's underside, where only a fall past the deck's edge takes it. Such a level has
        failed whatever follows (a bundle fell), in every mode: a body falling past the deck
        falls for ever in the sled's frame and would end the run as an energy blow-up, a
        collapse reported as an unphysical simulation (the 3-layer example unwrapped at 0.8 g,
        bundles 3.7 m off on the 2 m of deck beyond the pallet)."""
        below = np.flatnonzero(pos[:, 2] < -SLED_DECK_M)
        if not len(below):
            return ""
        name = self.scene.bodies[int(self.scene.moving[below[0]])].name
        return f"{name} fell off the sled"

    def _decided(self, pos: np.ndarray, rot: np.ndarray) -> str:
        """Why the level has already failed, whatever follows ("" if it has not): damage that
        cannot be undone (a bundle fallen off its support, a torn wrap) or an elastic
        displacement past its limit (the elastic figure is the maximum over the run)."""
        if self.wrap is not None and (self.wrap.rings.torn.any() or self.wrap.panels.torn.any()):
            return WRAP_TORN
        rel = in_pallet_frame(pos[PALLET], rot[PALLET], pos[BUNDLES])
        if self.reference is None:
            self.reference = rel
        tilt = np.arccos(np.clip(rot[BUNDLES, 2, 2], -1.0, 1.0))
        dropped = self.reference[:, 2] - rel[:, 2]
        fell = np.flatnonzero(fallen(pos[BUNDLES, 2], self.bottom_z, dropped, tilt))
        if len(fell):
            return f"{self.layout.bundles[fell[0]].name} fallen"
        elastic = norms((rel - self.reference)[:, :2]).max()
        limit = self.elastic_limit_m
        if elastic > limit:
            return f"elastic displacement {elastic * 1000:.0f} mm past {limit * 1000:.0f} mm"
        return ""

    def _apply_wrap(self, wrap: WrapNet, pos: np.ndarray, rot: np.ndarray, vel: np.ndarray,
                    omega: np.ndarray, t_s: float | None = None) -> None:
        force, torque = wrap.forces(pos, rot, vel, omega, t_s)
        bodies = np.flatnonzero(np.any(force != 0, axis=1) | np.any(torque != 0, axis=1))
        self.world.apply_wrenches(self.scene.moving[bodies], pos[bodies], force[bodies],
                                  torque[bodies], rot[bodies])

    def _settle(self) -> None:
        """Let the stack settle on the still sled; a wrap is laid at its wrapping tension,
        rising smoothly over the first two thirds of the settling time."""
        self.world.set_sled_accel(0.0)
        n = round(self.s.settle_s / self.s.timestep_s)
        for step in range(n):
            if self.wrap is not None:
                x = min(1.0, step / (2 * n / 3))
                self.wrap.laying(x * x * (3 - 2 * x))
                pos, rot, vel, omega = self._state()
                self._apply_wrap(self.wrap, pos, rot, vel, omega)
            self.world.step()
        if self.wrap is not None:
            pos, rot, _, _ = self._state()
            self.wrap.freeze(pos, rot)

    def execute(self, settle: bool = True) -> Trace:
        """Run the level (after settling and wrapping a fresh unit: `settle`)."""
        self.settled = settle
        if settle:
            self._settle()
        step: int | None = 0
        while step is not None:
            step = self._observe(step)
            if step is not None:
                self.world.set_sled_accel(float(self.accel[step + 1]))
                self.world.step()
                step += 1
        if self.deep_since is not None and not (self.invalid or self.stopped_early or
                                                self.not_at_rest):
            # at rest, no impact is still being pushed out (the depth was read at the last step)
            self.invalid = f"bodies interpenetrate by {self.depth_m * 1000:.0f} mm at rest"
            self.unsolved = "left bodies inside each other"
        return self._trace()

    def _observe(self, step: int) -> int | None:
        """Everything done between two steps: wrap forces, push, records, checks, contact
        states, rest. Returns the step to go on from (later than `step` after a skip), or None
        when the run ends."""
        pos, rot, vel, omega = self._state()
        if self.wrap is not None:
            self._apply_wrap(self.wrap, pos, rot, vel, omega, step * self.s.timestep_s)
        if self.push is not None and step < self.stop_step:
            self.world.push(self.push[0], self.push[1])
        self.samples.append((step * self.s.timestep_s, float(self.accel[step]), pos, rot))
        if step == 0 and self.settled:
            self.invalid = self._came_apart(pos)
            if self.invalid:
                return None
        self.stopped_early = self._off_the_sled(pos)
        if self.stopped_early:
            return None
        self._check(pos, vel, step)
        if self.invalid:
            return None
        if self.s.stop_when_decided:
            self.stopped_early = self._decided(pos, rot)
            if self.stopped_early:
                return None
        self._update_friction(pos, rot, vel, omega)
        return self._rest(step, pos, rot)

    def _rest(self, step: int, pos: np.ndarray, rot: np.ndarray) -> int | None:
        """End the run once everything has rested for `rest_hold_s` after the sled stopped
        (or `max_rest_wait_s` after it, at the latest); before that, with `skip_still`,
        record the steps in which nothing can change and skip them (see wrapenv.rest)."""
        s, dt = self.s, self.s.timestep_s
        held = step * dt - self.rest.observe(step, pos, rot) * dt >= s.rest_hold_s
        if step >= self.stop_step:
            if held:
                return None
            if step * dt < self.profile.duration_s + s.max_rest_wait_s:
                return step
            self.not_at_rest = f"still moving {s.max_rest_wait_s:g} s after the sled stopped"
            return None
        if not (held and s.skip_still):
            return step
        last = self.rest.unchanged_until(step, rot, self.stop_step)
        if last > step and not s.simulate_stop and self.rest.quiet_between(step, self.stop_step):
            last = self.stop_step  # what is left is quiet: taken to change nothing
        self.samples.extend((k * dt, float(self.accel[k]), pos, rot)
                            for k in range(step + 1, last + 1))
        return None if last == self.stop_step else last

    def _trace(self) -> Trace:
        t, a, pos, rot = zip(*self.samples, strict=True)
        pos_arr, rot_arr = np.array(pos), np.array(rot)
        return Trace(
            level_g=self.profile.level_g,
            load_height_m=self.layout.load_height_m,
            names=tuple(b.name for b in self.layout.bundles),
            bottom_z_m=self.bottom_z,
            t_s=np.array(t),
            sled_accel_mps2=np.array(a),
            pallet_pos_m=pos_arr[:, PALLET],
            pallet_rot=rot_arr[:, PALLET],
            bundle_pos_m=pos_arr[:, BUNDLES],
            bundle_rot=rot_arr[:, BUNDLES],
            valid=not self.invalid,
            invalid_reason=self.invalid,
            stopped_early=self.stopped_early,
            not_at_rest=self.not_at_rest,
            unsolved=self.unsolved,
            wrap=self.wrap.report() if self.wrap is not None else None,
            layers=np.array([b.layer for b in self.layout.bundles]),
            origin_m=self.origin_m,
        )

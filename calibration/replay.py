"""A tracked recording as the fit sees it, and the bench replaying it.

The camera sees world x; the bench simulates in the sled's frame. Both sides are therefore
compared as displacements relative to the sled, measured from each object's first tracked frame:
the sled's own motion, and any constant offset of a tracked centre, drop out. The bench is driven
by the recording's own profile.csv, sampled at the video's frame times, and stopped where the
last predictable window ends (`calibration.features`): what follows is not compared.

From the tracked paths alone we also learn which contact pairs slipped: a contact point (the
bottom centre of the upper body against the top centre of the lower one, rotations included, so
a column that tips does not count as slipping) that moved more than `SLIP_M` while the body
stood upright (`UPRIGHT_RAD`). A pair that never slipped cannot be fitted; the most it tells is
a lower bound of its static friction.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from calibration import features
from calibration.recording import Recording, image_angle_rad
from calibration.trajectories import ObjectPath, Trajectories
from wrapenv.bench import BenchUnit, SimSettings, run_level
from wrapenv.config import InputError
from wrapenv.load import PAIRS, Friction, FrictionPair, Layout, LoadUnit
from wrapenv.profile import G, MeasuredProfile, PulseProfile
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat

#: Relative motion across a contact beyond this (vision noise is ~1 mm) means the pair slipped.
SLIP_M = 0.005
#: A slip counts only within a stretch of frames in which the body stood within this angle of
#: upright. A body rocking on an edge by an angle a moves its bottom centre by l (1 - cos a) / 2
#: by geometry alone (0.5 mm at 5 degrees for a 0.28 m bundle, 4.8 mm at 15), and a column that
#: topples drags its bottom bundle along whatever that bundle's friction: the 3-layer example at
#: 0.32 g moved its bottom bundles 26-30 mm while they turned 16-37 degrees, under 1 mm while
#: within 5. Counted as slips, those made the pallet-bundle pair a fitted one and its fit
#: reported a kinetic coefficient 0.094 off at +- 0.013, where replays with the true value and
#: with it 0.084 lower were equally close to the recordings.
UPRIGHT_RAD = np.radians(5.0)
#: Fewer tracked frames than this cannot constrain a fit.
MIN_FRAMES = 10
#: The sled has stopped once its acceleration stays below this share of the pulse's peak: a
#: bench's braking is a quarter of it, an accelerometer's noise at rest a few per cent [A].
STOPPED_SHARE = 0.05
#: Replays meant to show the bench's run-to-run scatter let the unit settle this much longer
#: each (repeated bench tests never start from quite the same state).
SETTLE_STEP_S = 0.05
#: The wrapped unit's scalar parameters a calibration can fit: name -> the load and wrap
#: replayed with a value (the give is the load's: its bundles' edges under the web). One more
#: entry (and its range in `calibration.fit.WRAP_PARAMS`) adds a parameter.
WRAP_SCALES: dict[str, Callable[[LoadUnit, WrapFormat, float], tuple[LoadUnit, WrapFormat]]] = {
    "stiffness": lambda load, wrap, s: (load, wrap.scaled(stiffness_scale=s)),
    "tension": lambda load, wrap, s: (load, wrap.scaled(tension_scale=s)),
    "give": lambda load, wrap, s: (load.with_give(s), wrap),
}
#: A fit's values reach the bench rounded to these many decimals (a millionth of a friction
#: coefficient or of a wrap scale), and its residuals leave the replay rounded to a nanometre.
#: A search's arithmetic rounds its last bits differently from one processor to another
#: (numpy's AVX-512 loops against its AVX2 ones, OpenBLAS's kernels): on the 2-layer unit the
#: same fit's replayed slips differed by 1e-16 m, its surrogate's next points by 1e-13, and a
#: point 6e-13 apart became another run on the chaotic bench, so the fit ended elsewhere
#: (pallet-bundle's kinetic coefficient 0.4355 against 0.4366, bundle-bundle's 0.2962 against
#: 0.2933). Rounded, every processor replays the same points and fits the same numbers
#: (tests/calibration/test_determinism.py; docs/calibration.md, "The same fit on every
#: processor"). `wrapenv.bullet` rounds what the bench hands Bullet for the same reason.
VALUE_DECIMALS = 6
RESIDUAL_DECIMALS = 9


@dataclass(frozen=True)
class Observation:
    """One recording reduced to what the fit compares."""

    source: str
    load: LoadUnit
    wrap: WrapFormat | None
    profile: MeasuredProfile
    #: object -> (frame times on the profile's time base (n,), x and z displacement relative to
    #: the sled and rotation, from the first frame (n, 3))
    states: dict[str, tuple[np.ndarray, np.ndarray]]
    bodies: dict[str, features.Body]
    #: per compared body, the leading frames the bench can predict
    frames: dict[str, int]
    #: the recording's features (`features.vector`)
    target: np.ndarray
    slipped: frozenset[str]
    #: peak horizontal acceleration of the sled in g, backwards and forwards
    peak_accel_g: tuple[float, float]
    #: the levels (g) the unit ran before the take, which a replay runs first
    levels_before_g: tuple[float, ...] = ()

    @property
    def toppled(self) -> bool:
        """Whether a column toppled (`features.toppled`): it passes no more shear down to the
        pairs beneath it, however high the level."""
        return features.toppled(self.states, self.bodies)

    @property
    def end_s(self) -> float:
        """The last frame time any window reaches: the replay runs until then."""
        return max(float(self.states[n][0][k - 1]) for n, k in self.frames.items())


def observe(recording: Recording, tracked: Trajectories) -> Observation:
    """The displacements and slips the recording shows (`InputError` if it shows too little)."""
    src = str(recording.folder)
    layout = recording.load.layout()
    known = {"pallet"} | {b.name for b in layout.bundles}
    objects = {name: p for name, p in tracked.objects.items()
               if name in known and len(p.t_s) >= MIN_FRAMES}
    body_map = features.bodies(layout, set(objects))
    if not body_map:
        raise InputError(src, "trajectories", f"no object of the load tracked in "
                         f"{MIN_FRAMES} frames or more")
    sled = tracked.objects.get("sled")
    states = {name: (p.t_s, _relative(p, sled, recording)) for name, p in objects.items()}
    a = recording.profile.accel_mps2
    frames = features.windows(states, body_map, stop_s(recording.profile.t_s, a))
    body_map = features.reach(states, body_map, frames)
    profile = MeasuredProfile(recording.profile.t_s, a, src)
    return Observation(src, recording.load, recording.wrap, profile, states, body_map, frames,
                       features.vector(states, body_map, frames), _slipped(states, body_map),
                       (float(max(a.max(), 0.0)) / G, float(max(-a.min(), 0.0)) / G),
                       recording.levels_before_g)


def stop_s(t_s: np.ndarray, accel_mps2: np.ndarray) -> float:
    """When the sled stopped: its last acceleration above `STOPPED_SHARE` of the peak (a
    measured profile is never exactly 0 again; a synthetic one is, after its braking)."""
    moving = np.flatnonzero(np.abs(accel_mps2) > STOPPED_SHARE * np.max(np.abs(accel_mps2),
                                                                        initial=0.0))
    return float(t_s[moving[-1]]) if len(moving) else 0.0


def _sled_x(t: np.ndarray, sled: ObjectPath | None, recording: Recording) -> np.ndarray:
    """The sled's x at times t: as tracked when it was, else as profile.csv puts it."""
    if sled is not None and len(sled.t_s) >= MIN_FRAMES:
        return np.interp(t, sled.t_s, sled.x_m)
    return recording.profile.position_m(t)


def _relative(path: ObjectPath, sled: ObjectPath | None, recording: Recording) -> np.ndarray:
    x = path.x_m - _sled_x(path.t_s, sled, recording)
    xza = np.stack([x, path.z_m, path.angle_rad], axis=1)
    return xza - xza[0]


def _slipped(states: features.States, body_map: Mapping[str, features.Body]
             ) -> frozenset[str]:
    """The pairs across which a contact point moved more than `SLIP_M` while its body stood
    upright (whole paths)."""
    return frozenset(body_map[name].pair for name, slip in features.slips(states, body_map).items()
                     if upright_slide_m(slip, states[name][1][:, 2]) > SLIP_M)


def upright_slide_m(slip: np.ndarray, angle_rad: np.ndarray) -> float:
    """The largest change of a slip within one stretch of frames in which the body stood within
    `UPRIGHT_RAD` of upright (a slip carried over a rock and back does not count)."""
    upright = np.abs(angle_rad) <= UPRIGHT_RAD
    edges = np.flatnonzero(np.diff(np.concatenate(([0], upright.astype(int), [0]))))
    return max((float(np.ptp(slip[a:b])) for a, b in zip(edges[::2], edges[1::2], strict=True)),
               default=0.0)


def _rounded(friction: Friction) -> Friction:
    """The coefficients of every pair to `VALUE_DECIMALS`."""
    pairs = {name: friction.pair(name) for name in PAIRS}
    return Friction(**{name: FrictionPair(round(p.static, VALUE_DECIMALS),
                                          round(p.kinetic, VALUE_DECIMALS))
                       for name, p in pairs.items()})


def replay(obs: Observation, friction: Friction, scales: Mapping[str, float] | None = None,
           settings: SimSettings | None = None) -> dict[str, np.ndarray] | None:
    """Simulated displacements and rotations (n, 3) of the observed objects at their frame
    times, from the first one (as `Observation.states`), until the last window's end; None when
    the simulation became unphysical. `scales` maps `WRAP_SCALES` names to values. Both are
    replayed rounded to `VALUE_DECIMALS`."""
    load, wrap = obs.load.with_friction(_rounded(friction)), obs.wrap
    if wrap is not None:
        for name, value in (scales or {}).items():
            load, wrap = WRAP_SCALES[name](load, wrap, round(value, VALUE_DECIMALS))
    layout = load.layout()
    t, a = obs.profile.t_s, obs.profile.accel_mps2
    keep = t <= obs.end_s + (t[1] - t[0])
    profile = replace(obs.profile, t_s=t[keep], accel_mps2=a[keep])
    trace = _run_take(layout, profile, settings or SimSettings(), wrap, obs.levels_before_g)
    if trace is None or not trace.valid:
        return None
    index = {name: i for i, name in enumerate(trace.names)}
    out = {}
    for name, (t, _) in obs.states.items():
        j = index.get(name)
        pos = trace.pallet_pos_m if j is None else trace.bundle_pos_m[:, j]
        rot = trace.pallet_rot if j is None else trace.bundle_rot[:, j]
        angle = np.unwrap(image_angle_rad(rot))
        tau = np.clip(t - obs.profile.t_s[0], 0.0, trace.t_s[-1])
        xza = np.stack([np.interp(tau, trace.t_s, v) for v in (pos[:, 0], pos[:, 2], angle)],
                       axis=1)
        out[name] = xza - xza[0]
    return out


def _run_take(layout: Layout, profile: MeasuredProfile, settings: SimSettings,
              wrap: WrapFormat | None, levels_before_g: tuple[float, ...]) -> Trace | None:
    """The take on the bench, ended where its compared frames end (no wait for rest); a unit
    that ran levels before it runs them first, each to rest, as the lab ran them (None: one
    of them became unphysical). A Kraft-wrapped 2-layer unit at 0.7 g moves 0.7 mm after the
    levels 0.2 to 0.6 g, 4.5 mm fresh (benchmarks/carried_takes.py)."""
    if not levels_before_g:
        return run_level(layout, profile, replace(settings, max_rest_wait_s=0.0), wrap)
    with BenchUnit(layout, settings, wrap) as unit:
        for level_g in levels_before_g:
            if not unit.level(PulseProfile(level_g)).valid:
                return None
        return unit.level(profile, max_rest_wait_s=0.0)


def resettled(settings: SimSettings, k: int) -> SimSettings:
    """The settings of the k-th of several replays that are to differ as repeated tests do."""
    return replace(settings, settle_s=settings.settle_s + k * SETTLE_STEP_S)


def residuals(obs: Observation, simulated: Mapping[str, np.ndarray]) -> np.ndarray:
    """Simulated minus recorded features (`calibration.features`), in one vector, rounded to
    `RESIDUAL_DECIMALS` (metres)."""
    states = {name: (t, simulated[name]) for name, (t, _) in obs.states.items()}
    return (features.vector(states, obs.bodies, obs.frames) - obs.target).round(RESIDUAL_DECIMALS)

"""A tracked recording as the fit sees it, and the bench replaying it.

The camera sees world x; the bench simulates in the sled's frame. Both sides are therefore
compared as displacements relative to the sled, measured from each object's first tracked frame:
the sled's own motion, and any constant offset of a tracked centre, drop out. The bench is driven
by the recording's own profile.csv and sampled at the video's frame times.

From the tracked paths alone we also learn which contact pairs slipped: a contact point (the
bottom centre of the upper body against the top centre of the lower one, rotations included, so
a column that tips does not count as slipping) that moved more than `SLIP_M`. A pair that never
slipped cannot be fitted; the most it tells is a lower bound of its static friction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.recording import Recording
from calibration.trajectories import ObjectPath, Trajectories
from wrapenv.bench import SimSettings, run_level
from wrapenv.config import InputError
from wrapenv.load import Friction, Layout, LoadUnit
from wrapenv.profile import G, MeasuredProfile
from wrapenv.wrap import WrapFormat

#: Relative motion across a contact beyond this (vision noise is ~1 mm) means the pair slipped.
SLIP_M = 0.005
#: Fewer tracked frames than this cannot constrain a fit.
MIN_FRAMES = 10


@dataclass(frozen=True)
class Observation:
    """One recording reduced to what the fit compares."""

    source: str
    load: LoadUnit
    wrap: WrapFormat | None
    profile: MeasuredProfile
    #: object -> (frame times on the profile's time base (n,), displacement x, z (n, 2))
    paths: dict[str, tuple[np.ndarray, np.ndarray]]
    slipped: frozenset[str]
    #: peak horizontal acceleration of the sled in g, backwards and forwards
    peak_accel_g: tuple[float, float]

    @property
    def samples(self) -> int:
        return sum(len(t) for t, _ in self.paths.values())


def observe(recording: Recording, tracked: Trajectories) -> Observation:
    """The displacements and slips the recording shows (`InputError` if it shows too little)."""
    src = str(recording.folder)
    layout = recording.load.layout()
    heights = {"pallet": layout.pallet_size_m[2]} | {b.name: b.size_m[2] for b in layout.bundles}
    objects = {name: p for name, p in tracked.objects.items()
               if name in heights and len(p.t_s) >= MIN_FRAMES}
    if "pallet" not in objects and not any(n in heights for n in objects):
        raise InputError(src, "trajectories", f"no object of the load tracked in "
                         f"{MIN_FRAMES} frames or more")
    sled = tracked.objects.get("sled")
    paths = {name: (p.t_s, _relative(p, sled, recording)) for name, p in objects.items()}
    profile = MeasuredProfile(recording.profile.t_s, recording.profile.accel_mps2, src)
    a = recording.profile.accel_mps2
    return Observation(src, recording.load, recording.wrap, profile, paths,
                       _slipped(layout, objects, sled, recording, heights),
                       (float(max(a.max(), 0.0)) / G, float(max(-a.min(), 0.0)) / G))


def _sled_x(t: np.ndarray, sled: ObjectPath | None, recording: Recording) -> np.ndarray:
    """The sled's x at times t: as tracked when it was, else as profile.csv puts it."""
    if sled is not None and len(sled.t_s) >= MIN_FRAMES:
        return np.interp(t, sled.t_s, sled.x_m)
    return recording.profile.position_m(t)


def _relative(path: ObjectPath, sled: ObjectPath | None, recording: Recording) -> np.ndarray:
    x = path.x_m - _sled_x(path.t_s, sled, recording)
    xz = np.stack([x, path.z_m], axis=1)
    return xz - xz[0]


def _contact_x(path: ObjectPath, half_height: float, side: int, t: np.ndarray) -> np.ndarray:
    """World x of the bottom (side -1) or top (+1) centre of a body at times t."""
    x = np.interp(t, path.t_s, path.x_m)
    angle = np.interp(t, path.t_s, path.angle_rad)
    return x - side * half_height * np.sin(angle)


def _moved(upper: np.ndarray, lower: np.ndarray) -> bool:
    rel = upper - lower
    return bool(np.max(np.abs(rel - rel[0])) > SLIP_M)


def _slipped(layout: Layout, objects: dict[str, ObjectPath], sled: ObjectPath | None,
             recording: Recording, heights: dict[str, float]) -> frozenset[str]:
    pairs = set()
    pallet = objects.get("pallet")
    if pallet is not None:
        t = pallet.t_s
        if _moved(_contact_x(pallet, heights["pallet"] / 2, -1, t), _sled_x(t, sled, recording)):
            pairs.add("sled_pallet")
    supports = layout.supports()
    for b, below in zip(layout.bundles, supports, strict=True):
        upper = objects.get(b.name)
        if upper is None:
            continue
        lowers = ([("pallet", "pallet_bundle")] if b.layer == 1 else
                  [(layout.bundles[j].name, "bundle_bundle") for j in below])
        for name, pair in lowers:
            lower = objects.get(name)
            if lower is None:
                continue
            t = upper.t_s
            if _moved(_contact_x(upper, heights[b.name] / 2, -1, t),
                      _contact_x(lower, heights[name] / 2, +1, t)):
                pairs.add(pair)
    return frozenset(pairs)


def replay(obs: Observation, friction: Friction, stiffness_scale: float = 1.0,
           tension_scale: float = 1.0, settings: SimSettings | None = None
           ) -> dict[str, np.ndarray] | None:
    """Simulated displacements of the observed objects at their frame times, or None when the
    simulation became unphysical."""
    layout = obs.load.with_friction(friction).layout()
    wrap = obs.wrap.scaled(stiffness_scale, tension_scale) if obs.wrap is not None else None
    trace = run_level(layout, obs.profile, settings or SimSettings(), wrap)
    if not trace.valid:
        return None
    index = {name: i for i, name in enumerate(trace.names)}
    out = {}
    for name, (t, _) in obs.paths.items():
        xyz = trace.pallet_pos if name == "pallet" else trace.bundle_pos[:, index[name]]
        tau = np.clip(t - obs.profile.t_s[0], 0.0, trace.t_s[-1])
        xz = np.stack([np.interp(tau, trace.t_s, xyz[:, 0]),
                       np.interp(tau, trace.t_s, xyz[:, 2])], axis=1)
        out[name] = xz - xz[0]
    return out


def residuals(obs: Observation, simulated: dict[str, np.ndarray]) -> np.ndarray:
    """Simulated minus observed displacement, every object, frame and axis, in one vector."""
    return np.concatenate([(simulated[name] - disp).ravel()
                           for name, (_, disp) in obs.paths.items()])

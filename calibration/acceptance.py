"""Whether replays of a calibrated bench explain a recording: the fit's acceptance test.

A whole unit near its slip threshold is multi-modal: which bundle of a row slides is decided by
differences far below any parameter, so the same values replayed a few times send one body
sometimes one way, sometimes another, and the recording is one more such draw. Judged as one
vector, a recording whose one body took a mode the replays happened not to visit is refused
even with the true values (the 2-layer columnar unit: 13.7 mm unexplained, issue 13), while a
wrong value moves several bodies the same way in every replay.

So the test is per body, then per recording:
- a body's *unexplained* residual is what of the replays' mean residual (simulated minus
  recorded, over its features) the scatter a right model leaves does not account for: the
  replays' own run-to-run spread (the recording is one more draw, the mean of n replays keeps
  1/n of it) and the tracker's noise on the two positions a slip is the difference of;
- in each recording the least explained body in every `EXCUSED_PER_BODIES` is excused (a rare
  mode) and counts as explained (zero): the recording's unexplained RMS is over all its bodies,
  each counted once, so the limit means the same however many were excused;
- unless the single replay nearest the recording leaves less (beyond the tracker's noise),
  judged alike: a mode of the whole unit (the bottom layer slides or holds at its threshold)
  that few replays visit moves several bodies at once, and one replay in it suffices;
- the fit is refused when the worst recording's exceeds `FitSettings.max_residual_m`: a value
  one recording is sensitive to is judged there, not diluted by recordings blind to it.
Measured with `python -m benchmarks.bench_calibrate --truth N [--offset PAIR.KIND=DELTA]`; its power
against other rules: `python -m benchmarks.acceptance_power`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from calibration import features
from calibration.replay import Observation, residuals

#: One body in this many (rounded down) per recording may be in a mode its replays did not
#: visit: none of the pallet and four bundles of a small unit, one of a columnar row's nine.
EXCUSED_PER_BODIES = 8
#: What a right model leaves of a slip from the tracker alone: two tracked positions' noise.
NOISE_VAR_M2 = 2 * features.TRACK_NOISE_M**2

Runs = Sequence[Mapping[str, np.ndarray] | None]


@dataclass(frozen=True)
class Unexplained:
    """One recording's verdict: its unexplained RMS (metres, inf when a replay was
    unphysical) and the bodies excused from it."""

    source: str
    rms_m: float
    excused: tuple[str, ...] = ()
    #: what explained it: "the replays' mean", or "replay k" (the one nearest it)
    by: str = "the replays' mean"


def body_unexplained(r: np.ndarray) -> float:
    """Mean square (m^2) of one body's residuals r (replays x features) that a right model's
    scatter does not account for (see the module docstring)."""
    n = len(r)
    mean_sq = float(np.mean(r.mean(axis=0) ** 2))
    spread_sq = float(np.mean(r.var(axis=0, ddof=1))) * (1 + 1 / n) if n > 1 else 0.0
    return max(0.0, mean_sq - spread_sq - NOISE_VAR_M2)


def judge(unexplained_m2: dict[str, float], source: str = "") -> Unexplained:
    """A recording's verdict from its bodies' unexplained mean squares: the worst
    `1 / EXCUSED_PER_BODIES` of the bodies excused (counted as explained), every body counted
    once, however long its window (one that slides off early has few frames, and shows the
    friction most)."""
    order = sorted(unexplained_m2, key=lambda b: unexplained_m2[b], reverse=True)
    excused = tuple(order[:len(order) // EXCUSED_PER_BODIES])
    kept = sum(ms for b, ms in unexplained_m2.items() if b not in excused)
    return Unexplained(source, math.sqrt(kept / max(len(unexplained_m2), 1)), excused)


def recording(obs: Observation, runs: Runs) -> Unexplained:
    """How far `runs` (replays of one recording) leave it unexplained: by their mean and
    scatter, or by the one replay nearest it (a mode they visited), whichever leaves less."""
    if not runs or any(run is None for run in runs):
        return Unexplained(obs.source, math.inf)
    r = np.array([residuals(obs, run) for run in runs if run is not None])
    return by_residuals(r, features.spans(obs.frames), obs.source)


def by_residuals(r: np.ndarray, spans: Mapping[str, np.ndarray], source: str = ""
                 ) -> Unexplained:
    """`recording`'s verdict from the replays' residuals r (replays x features, simulated minus
    recorded) and each body's features (`features.spans`)."""
    by_mean = judge({name: body_unexplained(r[:, idx]) for name, idx in spans.items()}, source)
    nearest = [judge({name: max(0.0, float(np.mean(one[idx] ** 2)) - NOISE_VAR_M2)
                      for name, idx in spans.items()}, source) for one in r]
    k = int(np.argmin([v.rms_m for v in nearest]))
    if nearest[k].rms_m < by_mean.rms_m:
        return replace(nearest[k], by=f"replay {k}")
    return by_mean


def worst(observations: Sequence[Observation], replays: Sequence[Runs]) -> Unexplained:
    """The recording the replays explain least: the fit's verdict (its `rms_m` is what
    `max_residual_m` bounds)."""
    verdicts = [recording(o, runs) for o, runs in zip(observations, replays, strict=True)]
    return max(verdicts, key=lambda v: v.rms_m, default=Unexplained("", 0.0))

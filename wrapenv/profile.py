"""Sled acceleration profiles: the ESTL pulse for a test level, or a measured profile.

A profile is a function of time a(t) (m/s², + along x) that starts and ends with the sled at
rest. The pulse follows the ESTL bench (paper, section 2) and EUMOS 40509: the level k·g is
reached within `ramp_s`, held for `dwell_s` (EUMOS asks at least 0.3 s, the ESTL bench holds at
least 0.5 s), then turns into a constant, gentler deceleration until the sled stops, so the stop
adds no deformation of its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wrapenv.config import InputError, read_csv

#: Gravity (m/s²), by which levels are given in g; the bench's world pulls down with it too.
G = 9.81
#: The ESTL bench produces 0 to 10 m/s² (paper, section 2): the highest level it can run is 1.0 g.
BENCH_MAX_ACCEL_MPS2 = 10.0
LEVEL_STEP_G = 0.1
MIN_DWELL_S = 0.3
#: Longest measured profile accepted [A]: a test is a pulse and a few seconds of run-out (the
#: source paper's recordings last 8 to 10 s), and a logger left running adds quiet ones (a level
#: ends once nothing more can happen); longer is a unit mistake, such as t_s in milliseconds.
#: One bound for every measured profile, a recording's (`calibration.recording`) included: a
#: recording's profile is one the bench can be driven by.
MAX_PROFILE_S = 120.0
#: The highest level in g, rounded down so that the quoted bound is itself accepted.
MAX_LEVEL_TEXT = f"{int(BENCH_MAX_ACCEL_MPS2 / G * 1000) / 1000:.3f}"


def _level_ok(level_g: float) -> bool:
    return math.isfinite(level_g) and 0 < level_g * G <= BENCH_MAX_ACCEL_MPS2 + 1e-9


def _level_range(level_g: float) -> str:
    """Why a level is refused, and, for one the bench reaches in m/s², that it reads as m/s²."""
    text = f"must be in (0, {MAX_LEVEL_TEXT}] g, the bench's 10 m/s² (got {level_g})"
    if math.isfinite(level_g) and 1 < level_g <= BENCH_MAX_ACCEL_MPS2 + 1e-9:
        text += f": m/s²? Levels are in g ({level_g:g} m/s² is {level_g / G:.2f} g)"
    return text


@dataclass(frozen=True)
class PulseProfile:
    """The bench pulse for one test level."""

    level_g: float
    ramp_s: float = 0.05
    dwell_s: float = 0.5
    #: Deceleration as a fraction of the level [A]: no source gives the ESTL sled's braking;
    #: 0.25 stops it in about 4 x dwell. Up to 0.8 g that is at most 0.2 g, below the default
    #: static coefficients (0.30) but above a 3-layer column's tipping level (0.19 g), so the
    #: stop can move a unit at the highest levels: the bench simulates it.
    decel_ratio: float = 0.25

    def __post_init__(self) -> None:
        if not _level_ok(self.level_g):
            raise InputError("profile", "level_g", _level_range(self.level_g))
        if not (math.isfinite(self.dwell_s) and self.dwell_s >= MIN_DWELL_S):
            raise InputError("profile", "dwell_s", f"must be >= {MIN_DWELL_S} s (EUMOS 40509)")
        if not (math.isfinite(self.ramp_s) and 0 <= self.ramp_s <= self.dwell_s):
            raise InputError("profile", "ramp_s", "must be between 0 and dwell_s")
        if not (math.isfinite(self.decel_ratio) and 0 < self.decel_ratio <= 1):
            raise InputError("profile", "decel_ratio", "must be in (0, 1]")

    @property
    def peak_mps2(self) -> float:
        return self.level_g * G

    def _phases(self) -> tuple[float, float, float, float, float]:
        """Times: end of ramp up, end of dwell, end of ramp down, stop; and the deceleration."""
        a, r = self.peak_mps2, self.ramp_s
        d = self.decel_ratio * a
        r_down = r * (a + d) / a  # same jerk as the ramp up
        t1, t2 = r, r + self.dwell_s
        t3 = t2 + r_down
        # Velocity at t3: ramps contribute their mean acceleration times their length.
        v3 = a * r / 2 + a * self.dwell_s + (a - d) / 2 * r_down
        return t1, t2, t3, t3 + v3 / d, d

    @property
    def duration_s(self) -> float:
        return self._phases()[3]

    def describe(self) -> str:
        """The pulse's shape, as a test report states its conditions."""
        return (f"the level reached in {self.ramp_s:g} s, held {self.dwell_s:g} s, then braked "
                f"at {self.decel_ratio:g} of it to a stop")

    def accel(self, t: float | np.ndarray) -> np.ndarray:
        t1, t2, t3, t4, d = self._phases()
        a = self.peak_mps2
        t = np.asarray(t, dtype=float)
        ramp_up = a * np.clip(t / t1, 0, 1) if t1 > 0 else np.where(t >= 0, a, 0.0)
        down = np.clip((t - t2) / (t3 - t2), 0, 1) if t3 > t2 else (t >= t2).astype(float)
        out = ramp_up - down * (a + d)
        return np.where((t < 0) | (t >= t4), 0.0, out)


#: A measured sled peaking below this is unlike any bench test (EUMOS 40509 starts at 0.2 g): an
#: acceleration column written in g instead of m/s² reads about ten times too low.
LOW_PEAK_G = 0.15


def profile_warnings(source: str, accel_mps2: np.ndarray) -> tuple[str, ...]:
    """What a measured profile holds that a bench test hardly does, each a sentence naming
    `source`: a peak below any bench level (a column in g?) or beyond the bench's (a spike?),
    or a deceleration stronger than the forward pulse (an accelerometer mounted the other way
    round, or a bench that tests by braking, whose level the forward peak does not give and
    whose load the stop bar behind the pallet does not hold)."""
    forward, backward = float(np.max(accel_mps2)), float(-np.min(accel_mps2))
    out = []
    if backward > forward:
        out.append(f"{source}: accel_mps2 brakes harder ({backward:.2f} m/s², "
                   f"{backward / G:.3f} g) than it accelerates ({forward:.2f} m/s²): the bench "
                   "takes +x as the sled's direction of travel and reports the forward peak "
                   "as the level; if the accelerometer is mounted the other way round, negate "
                   "the column")
    elif forward < LOW_PEAK_G * G:
        out.append(f"{source}: accel_mps2 peaks at {forward:.2f} m/s² ({forward / G:.3f} g), "
                   "below any bench level (EUMOS 40509 starts at 0.2 g): is the column in g? "
                   "It must be in m/s²")
    if max(forward, backward) > BENCH_MAX_ACCEL_MPS2:
        out.append(f"{source}: accel_mps2 reaches {max(forward, backward):.2f} m/s², beyond "
                   f"the ESTL bench's {BENCH_MAX_ACCEL_MPS2:g} m/s² (the highest level it runs "
                   "is 1.0 g): a spike in the recording, or a profile of another bench? It is "
                   "simulated as given")
    return tuple(out)


@dataclass(frozen=True)
class MeasuredProfile:
    """A sled acceleration recorded on a bench (`profile.csv`), sampled at `t_s`."""

    t_s: np.ndarray
    accel_mps2: np.ndarray
    source: str = "profile.csv"

    @property
    def peak_mps2(self) -> float:
        return float(np.max(self.accel_mps2))

    @property
    def level_g(self) -> float:
        return self.peak_mps2 / G

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    def describe(self) -> str:
        """Where the sled's motion came from, as a test report states its conditions."""
        return (f"the sled's measured profile {self.source} ({self.duration_s:.2f} s, peak "
                f"{self.level_g:.3f} g)")

    def warnings(self) -> tuple[str, ...]:
        """What the file holds that a bench test hardly does (`profile_warnings`)."""
        return profile_warnings(self.source, self.accel_mps2)

    def accel(self, t: float | np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float) + self.t_s[0]
        inside = (t >= self.t_s[0]) & (t <= self.t_s[-1])
        return np.where(inside, np.interp(t, self.t_s, self.accel_mps2), 0.0)

    @classmethod
    def from_csv(cls, path: str | Path) -> MeasuredProfile:
        src = str(path)
        columns = read_profile_csv(path)
        t_arr, a_arr = columns["t_s"], columns["accel_mps2"]
        if np.max(np.abs(a_arr)) > BENCH_MAX_ACCEL_MPS2 * 2:
            raise InputError(src, "accel_mps2",
                             f"peak {np.max(np.abs(a_arr)):.1f} m/s² is beyond any bench")
        if np.max(a_arr) <= 0:
            raise InputError(src, "accel_mps2", "has no forward acceleration")
        return cls(t_arr, a_arr, src)


Profile = PulseProfile | MeasuredProfile


def read_profile_csv(path: str | Path, optional: tuple[str, ...] = ()
                     ) -> dict[str, np.ndarray]:
    """A sled profile file's columns: t_s and accel_mps2, and those of `optional` it has; every
    value finite, at least two samples, time increasing strictly over no more than a sled run
    lasts. What is read as a test's profile (`MeasuredProfile`) and what a recording's sled
    did (calibration's `SledProfile`) are checked alike."""
    src = str(path)
    header, rows = read_csv(path)
    for col in ("t_s", "accel_mps2"):
        if col not in header:
            raise InputError(src, col, "missing column (header must name t_s,accel_mps2)")
    present = ["t_s", "accel_mps2", *(c for c in optional if c in header)]
    at = [header.index(c) for c in present]
    values = []
    for line, row in rows:
        try:
            values.append([float(row[i]) for i in at])
        except (ValueError, IndexError):
            raise InputError(src, f"line {line}", f"not a number row: {row!r}") from None
    table = np.array(values, float).reshape(-1, len(present))
    columns = {c: table[:, j] for j, c in enumerate(present)}
    t = columns["t_s"]
    if len(t) < 2:
        raise InputError(src, "t_s", "needs at least two samples")
    for col, column in columns.items():
        if not np.all(np.isfinite(column)):
            raise InputError(src, col, "contains NaN or infinite values")
    if np.any(np.diff(t) <= 0):
        raise InputError(src, "t_s", "must increase strictly")
    if t[-1] - t[0] > MAX_PROFILE_S:
        raise InputError(src, "t_s", f"spans {t[-1] - t[0]:g} s, longer than the "
                         f"{MAX_PROFILE_S:g} s a sled run lasts (times in milliseconds?)")
    return columns


#: Where a bench lab starts the sequence (0.2 or 0.3 g, paper section 2).
START_G = 0.2


def g_text(level_g: float) -> str:
    """A level in g as tables and messages show it: two decimals, three where two would round it
    onto another level (0.495 and 0.5 g are not both "0.50"; a take at 0.425 g is not 0.42)."""
    return f"{level_g:.2f}" if abs(level_g - round(level_g, 2)) < 1e-9 else f"{level_g:.3f}"


def target_warnings(target_g: float) -> tuple[str, ...]:
    """A target below EUMOS 40509's first level. It is run, not refused (a lighter check has
    its uses), but its pass is no pass of the standard: a new user read one as such."""
    if target_g >= START_G - 1e-9:
        return ()
    return (f"a target of {target_g:g} g lies below EUMOS 40509's first level ({START_G:g} g): "
            "the sequence is that one level, a check short of the standard",)


def eumos_levels(target_g: float = 0.5, start_g: float | None = None) -> list[float]:
    """The EUMOS 40509 sequence: start (0.2 or 0.3 g), then +0.1 g up to and including target.
    Without a start, 0.2 g, or the target itself when it is lower."""
    if start_g is None:
        start_g = min(START_G, target_g) if math.isfinite(target_g) else START_G
    if not _level_ok(target_g):
        raise InputError("test sequence", "target_g", _level_range(target_g))
    if not (math.isfinite(start_g) and 0 < start_g <= target_g + 1e-9):
        raise InputError("test sequence", "start_g", f"must be in (0, target] (got {start_g})")
    n = math.floor((target_g - start_g) / LEVEL_STEP_G + 1e-9)
    levels = [round(start_g + i * LEVEL_STEP_G, 3) for i in range(n + 1)]
    if levels[-1] < target_g - 1e-9:
        levels.append(round(target_g, 3))
    return levels

"""A fit's checkpoint: the search's replays as data (JSON Lines), never a pickle.

A fit is deterministic for its seed, so resuming one is running it again with the replays it
already made taken from the file instead of simulated. Each line holds one replay: a key that
names everything the replay depends on (the recording as observed, the friction and wrap
scales it was given, the bench's settings) and the residual vector it gave (null: it became
unphysical). A hit is therefore exactly what the simulation would return, and a resumed fit
writes the CAL.json the uninterrupted one would. Lines are appended as replays finish, so an
interrupted fit loses at most the replays under way; a last line cut off mid-write is ignored.
The first line names the recordings and the version of wrapbench; a checkpoint of other
recordings, or of another version's bench, is refused.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from calibration.replay import Observation
from wrapenv import __version__
from wrapenv.bench import SimSettings
from wrapenv.config import InputError, is_finite_number
from wrapenv.load import Friction

#: Every version of the format starts so: what an existing file must be to be overwritten.
FORMAT_FAMILY = "wrapbench-calibration-replays/"
#: 2 since 2026-12-05: replays run the fit's values to a millionth and give residuals to a
#: nanometre (`replay.VALUE_DECIMALS`); a version-1 file's replays are not what this bench
#: would return, and a fit resumed from them would not write the uninterrupted fit's CAL.json.
CHECKPOINT_FORMAT = FORMAT_FAMILY + "2"


def recording_key(obs: Observation) -> str:
    """What a replay of `obs` depends on, hashed: its load, wrap and profile, the frames the fit
    compares, the recorded features they are compared with, and the levels the unit ran before
    the take (only where it ran any: a fresh take's key is as it was before they were read)."""
    h = hashlib.sha256()
    for part in (repr(obs.load), repr(obs.wrap), repr(sorted(obs.frames.items()))):
        h.update(part.encode())
    if obs.levels_before_g:
        h.update(repr(obs.levels_before_g).encode())
    for array in (obs.profile.t_s, obs.profile.accel_mps2, obs.target):
        h.update(np.ascontiguousarray(array, dtype=float).tobytes())
    return h.hexdigest()


def replay_key(recording: str, friction: Friction, scales: Mapping[str, float],
               sim: SimSettings) -> str:
    """One replay's key: the recording's and everything the replay is given."""
    text = repr((recording, friction, sorted(scales.items()), sim))
    return hashlib.sha256(text.encode()).hexdigest()


class ReplayLog:
    """The replays of a fit so far, read from and appended to `path` (a context manager)."""

    def __init__(self, path: Path, observations: Sequence[Observation], resume: bool) -> None:
        self.path = path
        self.recordings = {id(obs): recording_key(obs) for obs in observations}
        names = sorted(set(self.recordings.values()))
        self.known: dict[str, np.ndarray | None] = _read(path, names) if resume else {}
        self.reused = 0
        self._file: IO[str] = path.open("a" if resume else "w", encoding="utf-8")
        if not resume:
            self._write({"format": CHECKPOINT_FORMAT, "wrapbench_version": __version__,
                         "recordings": names})

    def key(self, obs: Observation, friction: Friction, scales: Mapping[str, float],
            sim: SimSettings) -> str:
        recording = self.recordings.get(id(obs)) or recording_key(obs)
        return replay_key(recording, friction, scales, sim)

    def get(self, key: str) -> tuple[bool, np.ndarray | None]:
        """(True, residuals) for a replay the checkpoint holds, else (False, None)."""
        if key not in self.known:
            return False, None
        self.reused += 1
        return True, self.known[key]

    def add(self, key: str, residuals: np.ndarray | None) -> None:
        self.known[key] = residuals
        self._write({"replay": key,
                     "residuals": None if residuals is None else residuals.tolist()})

    def _write(self, line: dict[str, Any]) -> None:
        self._file.write(json.dumps(line) + "\n")
        self._file.flush()

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> ReplayLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _read(path: Path, recordings: list[str]) -> dict[str, np.ndarray | None]:
    """The replays a checkpoint holds, if it is one of these recordings."""
    try:
        lines = path.read_text(encoding="utf-8").split("\n")
    except FileNotFoundError:
        raise InputError(str(path), "--resume", "no checkpoint to resume from") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(str(path), "", f"cannot read the checkpoint ({exc})") from None
    complete = lines[:-1]   # the text after the last newline: "" or a line cut off mid-write
    if not complete:
        raise InputError(str(path), "line 1", "empty: not a wrapbench calibration checkpoint")
    head = _parse(path, 1, complete[0])
    if head.get("format") != CHECKPOINT_FORMAT:
        raise InputError(str(path), "format", f"not a wrapbench calibration checkpoint of this "
                                              f"version ({CHECKPOINT_FORMAT})")
    if head.get("wrapbench_version") != __version__:
        raise InputError(str(path), "wrapbench_version", f"written by wrapbench "
                         f"{head.get('wrapbench_version')}, not {__version__}: its replays are "
                         "another bench's")
    if head.get("recordings") != recordings:
        raise InputError(str(path), "recordings", "the checkpoint is of other recordings (or "
                                                  "their tracked paths changed since)")
    known = {}
    for number, text in enumerate(complete[1:], start=2):
        key, residuals = _replay(path, number, _parse(path, number, text))
        known[key] = residuals
    return known


def _parse(path: Path, number: int, text: str) -> dict[str, Any]:
    try:
        line = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(str(path), f"line {number}", f"malformed JSON ({exc})") from None
    if not isinstance(line, dict):
        raise InputError(str(path), f"line {number}", "expected a JSON object")
    return line


def _replay(path: Path, number: int, line: dict[str, Any]) -> tuple[str, np.ndarray | None]:
    """One replay line: a key and finite residuals (or null), as the fit writes them."""
    key, residuals = line.get("replay"), line.get("residuals")
    if not (isinstance(key, str) and len(key) == 64 and set(key) <= set("0123456789abcdef")):
        raise InputError(str(path), f"line {number}.replay", "must be a replay's key")
    if residuals is None:
        return key, None
    if not (isinstance(residuals, list) and residuals
            and all(map(is_finite_number, residuals))):
        raise InputError(str(path), f"line {number}.residuals",
                         "must be null or a list of finite numbers")
    return key, np.array(residuals, dtype=float)


__all__ = ["CHECKPOINT_FORMAT", "ReplayLog", "recording_key", "replay_key"]

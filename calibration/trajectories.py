"""Tracked object paths in CONTRACTS.md's `trajectories.csv` format, and their error against truth.

The CSV is the hand-off from vision to fitting (`t_s,object,x_m,z_m,angle_rad`, absolute world
metres, one row per visible object and frame), so reading validates it as strictly as any other
user file: a bad row names the file, the line and the column.
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wrapenv.config import InputError, read_csv, write_atomic

HEADER = ("t_s", "object", "x_m", "z_m", "angle_rad")
#: No tracked centre lies farther from the camera's origin than this: a sled run travels a few
#: metres and a load stands under 3 m. Beyond it a file is in millimetres (another tracker's).
MAX_POSITION_M = 100.0
#: No object turns farther than this on a bench: a fallen bundle lies a quarter turn over, and
#: one tumbling off the sled was tracked through 7.9 rad (its angle unwrapped frame to frame).
#: Beyond two turns an angle is in degrees.
MAX_ANGLE_RAD = 4 * math.pi


@dataclass(frozen=True, eq=False)
class ObjectPath:
    """One object's centre (world x, z) and rotation about the camera axis per frame it was
    seen in, times strictly increasing: as tracked, and as truth.json gives it."""

    t_s: np.ndarray
    x_m: np.ndarray
    z_m: np.ndarray
    angle_rad: np.ndarray


@dataclass(frozen=True)
class Trajectories:
    """Per-object paths, keyed by the contract's names (`sled`, `pallet`, `L1C1R1`, ...)."""

    objects: dict[str, ObjectPath]

    def to_csv(self, path: str | Path) -> None:
        """Write the contract's CSV atomically, rows ordered by time, then object name."""
        rows = [
            (t, name, x, z, a)
            for name, p in self.objects.items()
            for t, x, z, a in zip(p.t_s, p.x_m, p.z_m, p.angle_rad, strict=True)
        ]
        rows.sort(key=lambda r: (r[0], r[1]))
        out = io.StringIO()
        out.write(",".join(HEADER) + "\n")
        for t, name, x, z, a in rows:
            out.write(f"{t:.6f},{name},{x:.6f},{z:.6f},{a:.6f}\n")
        write_atomic(path, out.getvalue().encode())

    @classmethod
    def from_csv(cls, path: str | Path) -> Trajectories:
        """Read and validate a trajectories CSV; any defect raises `InputError` naming the line."""
        path = Path(path)
        header, rows = read_csv(path)
        if tuple(header) != HEADER:
            raise InputError(str(path), "header", f"must be {','.join(HEADER)} (got {header})")
        columns: dict[str, list[tuple[float, float, float, float]]] = {}
        for line, row in rows:
            if len(row) != len(HEADER):
                raise InputError(str(path), f"line {line}", f"expected 5 columns, got {len(row)}")
            name = row[1].strip()
            if not name:
                raise InputError(str(path), f"line {line}: object", "empty name")
            columns.setdefault(name, []).append(_numbers(path, line, row))
        if not columns:
            raise InputError(str(path), "", "no rows")
        objects = {}
        for name, values in columns.items():
            t, x, z, a = (np.array(c) for c in zip(*values, strict=True))
            if np.any(np.diff(t) <= 0):
                raise InputError(str(path), f"object {name}", "times must strictly increase")
            objects[name] = ObjectPath(t, x, z, a)
        return cls(objects)


def _numbers(path: Path, line: int, row: list[str]) -> tuple[float, float, float, float]:
    values = []
    for key, cell in zip((HEADER[0], *HEADER[2:]), (row[0], *row[2:]), strict=True):
        try:
            value = float(cell)
        except ValueError:
            raise InputError(str(path), f"line {line}: {key}", f"not a number ({cell!r})") from None
        if not math.isfinite(value):
            raise InputError(str(path), f"line {line}: {key}", f"must be finite (got {cell})")
        if key in ("x_m", "z_m") and abs(value) > MAX_POSITION_M:
            raise InputError(str(path), f"line {line}: {key}",
                             f"{value:g} m from the camera's origin, beyond any bench "
                             f"({MAX_POSITION_M:g} m): millimetres? Positions are in metres")
        if key == "angle_rad" and abs(value) > MAX_ANGLE_RAD:
            raise InputError(str(path), f"line {line}: {key}",
                             f"{value:g} rad, more than two whole turns: degrees? Angles are in "
                             "radians")
        values.append(value)
    return values[0], values[1], values[2], values[3]


@dataclass(frozen=True)
class PathError:
    """Displacement error of one object: both paths measured from their values at the first
    tracked time, so a constant offset of the start (e.g. the template's centre) does not count;
    `offset_m` reports that start offset separately."""

    rms_m: float
    max_m: float
    offset_m: float
    frames: int


def error_vs_truth(tracked: Trajectories, truth: Mapping[str, ObjectPath]
                   ) -> dict[str, PathError]:
    """Per object in both: RMS and max of |displacement error| (x, z), truth interpolated to the
    tracked times (tracked frames outside the truth's time span are ignored)."""
    errors = {}
    for name, path in tracked.objects.items():
        if name not in truth:
            continue
        ref = truth[name]
        t_ref = np.asarray(ref.t_s, float)
        keep = (path.t_s >= t_ref[0]) & (path.t_s <= t_ref[-1])
        if not np.any(keep):
            continue
        t = path.t_s[keep]
        x_true = np.interp(t, t_ref, np.asarray(ref.x_m, float))
        z_true = np.interp(t, t_ref, np.asarray(ref.z_m, float))
        dx = (path.x_m[keep] - path.x_m[keep][0]) - (x_true - x_true[0])
        dz = (path.z_m[keep] - path.z_m[keep][0]) - (z_true - z_true[0])
        err = np.hypot(dx, dz)
        offset = math.hypot(path.x_m[keep][0] - x_true[0], path.z_m[keep][0] - z_true[0])
        errors[name] = PathError(float(np.sqrt(np.mean(err**2))), float(err.max()), offset, t.size)
    return errors

"""Checks on tracked paths that become warnings, and frame lists written as ranges for them."""

from __future__ import annotations

import numpy as np

from calibration.trajectories import ObjectPath


def frame_ranges(frames: list[int]) -> str:
    """[1, 2, 3, 7] -> "1-3, 7"."""
    out, start = [], 0
    for k in range(1, len(frames) + 1):
        if k == len(frames) or frames[k] != frames[k - 1] + 1:
            first, last = frames[start], frames[k - 1]
            out.append(f"{first}-{last}" if last > first else f"{first}")
            start = k
    return ", ".join(out)


def swap_warnings(paths: dict[str, ObjectPath], half_m: dict[str, float],
                  fps: float) -> list[str]:
    """Pairs of objects whose centres come closer than the smaller of their half-boxes
    (`half_m`, objects without one are not checked): one tracker may have jumped to its
    neighbour."""
    names = [n for n in paths if n in half_m]
    warnings = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            pa, pb = paths[a], paths[b]
            common, ia, ib = np.intersect1d(pa.t_s, pb.t_s, return_indices=True)
            if common.size == 0:
                continue
            d = np.hypot(pa.x_m[ia] - pb.x_m[ib], pa.z_m[ia] - pb.z_m[ib])
            close = d < min(half_m[a], half_m[b])
            if np.any(close):
                frames = np.rint(common[close] * fps).astype(int).tolist()
                warnings.append(f"{a} and {b} overlap in frames {frame_ranges(frames)}: their "
                                "identities may have swapped")
    return warnings


def gap_warnings(name: str, seen: list[int], frames: int) -> list[str]:
    """The frames of `frames` in which object `name` was not `seen` (sorted, not empty): those
    between its first and last sighting are interpolated, those outside them left out of its
    path."""
    missing = sorted(set(range(frames)) - set(seen))
    if not missing:
        return []
    inside = [k for k in missing if seen[0] < k < seen[-1]]
    outside = [k for k in missing if k < seen[0] or k > seen[-1]]
    note = ([f"frames {frame_ranges(inside)} interpolated"] if inside else []) + (
        [f"frames {frame_ranges(outside)} left out"] if outside else [])
    return [f"{name}: no marker followed in {len(missing)} frames ({'; '.join(note)})"]

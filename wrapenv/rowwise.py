"""Row-wise vector operations on the small arrays a step works on.

numpy's general routines carry per-call overhead that dominates on arrays of tens of rows, and
they run every Bullet step; these compute the same floating-point operations in the same order
(so results are bit for bit those of `np.linalg.norm` and `np.cross`) without it.
"""

from __future__ import annotations

import numpy as np


def norms(x: np.ndarray) -> np.ndarray:
    """Euclidean norms along the last axis: `np.linalg.norm(x, axis=-1)`, which computes
    exactly this for real arrays."""
    return np.sqrt(np.add.reduce(x * x, axis=-1))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of the rows of two (n, 3) arrays of one shape."""
    out = np.empty(a.shape)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out

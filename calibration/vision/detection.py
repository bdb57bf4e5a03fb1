"""Finding the bundles in a frame: normalised cross-correlation, non-maximum suppression and a
sub-pixel peak.

`cv2.matchTemplate` (TM_CCOEFF_NORMED) scores every placement of the template; neighbouring
placements of one bundle all score high, so NMS keeps the best of each cluster (greedy over the
few local maxima, which keeps the cost independent of the image size). A parabola through the
peak and its neighbours gives the centre to a tenth of a pixel, which the tracker's absolute
positions start from.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Detection:
    """A template match: centre (u, v) in image pixels, NCC score, box size."""

    u: float
    v: float
    score: float
    width: int
    height: int


def ncc(image: np.ndarray, template: np.ndarray) -> np.ndarray:
    """TM_CCOEFF_NORMED scores; flat placements (NaN/inf) score 0."""
    scores = cv2.matchTemplate(image, template, cv2.TM_CCOEFF_NORMED)
    return np.nan_to_num(scores, nan=0.0, posinf=0.0, neginf=0.0)


def subpixel_peak(scores: np.ndarray, row: int, col: int) -> tuple[float, float]:
    """Offsets (d_col, d_row) in [-0.5, 0.5] of a parabola's vertex through the peak's 3-neighbours.

    At the map's edge the offset along that axis is 0: the peak is then not bracketed.
    """

    def vertex(a: float, b: float, c: float) -> float:
        denom = a - 2 * b + c
        return 0.0 if denom >= 0 else float(np.clip(0.5 * (a - c) / denom, -0.5, 0.5))

    h, w = scores.shape
    dc = vertex(*scores[row, col - 1:col + 2]) if 0 < col < w - 1 else 0.0
    dr = vertex(*scores[row - 1:row + 2, col]) if 0 < row < h - 1 else 0.0
    return dc, dr


def nms(centres: np.ndarray, scores: np.ndarray, size: tuple[int, int],
        max_iou: float = 0.3) -> np.ndarray:
    """Indexes of the boxes (all of `size`, centred on `centres` (n, 2)) kept by greedy NMS,
    best first: a box is dropped when it overlaps a kept one by more than `max_iou`."""
    w, h = size
    order = np.argsort(-scores)
    kept: list[int] = []
    for i in order:
        if kept:
            d = np.abs(centres[kept] - centres[i])
            inter = np.clip(w - d[:, 0], 0, None) * np.clip(h - d[:, 1], 0, None)
            if np.any(inter / (2 * w * h - inter) > max_iou):
                continue
        kept.append(int(i))
    return np.array(kept, int)


def find_template(image: np.ndarray, template: np.ndarray, threshold: float,
                  max_iou: float = 0.3) -> list[Detection]:
    """All placements of `template` in `image` scoring >= `threshold`, after NMS, with sub-pixel
    centres in `image`'s pixel coordinates (pixel (c, r) centred on u = c, v = r)."""
    th, tw = template.shape[:2]
    if image.shape[0] < th or image.shape[1] < tw:
        return []
    scores = ncc(image, template)
    local_max = scores >= cv2.dilate(scores, np.ones((3, 3), np.uint8))
    rows, cols = np.nonzero(local_max & (scores >= threshold))
    if rows.size == 0:
        return []
    centres = np.stack([cols, rows], axis=1).astype(float)
    keep = nms(centres, scores[rows, cols], (tw, th), max_iou)
    detections = []
    for i in keep:
        dc, dr = subpixel_peak(scores, rows[i], cols[i])
        detections.append(Detection(cols[i] + dc + (tw - 1) / 2, rows[i] + dr + (th - 1) / 2,
                                    float(scores[rows[i], cols[i]]), tw, th))
    return detections

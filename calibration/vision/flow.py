"""Farnebäck optical flow inside a tracked box, reduced to the box's rigid motion.

The paper takes the centre of gravity as a weighted mean of the flow in the bounding box. Here
the flow is computed between the object's first-frame patch and the current frame warped back
by the current estimate, so it measures only the small residual motion (where Farnebäck is
most accurate) and errors never accumulate from frame to frame. The residual field is fitted by
weighted least squares with a translation and a small rotation about the centre, weights being
the patch's texture strength (smallest structure-tensor eigenvalue: edges alone only fix the
motion across them) and, in a second pass, agreement with the fit (Cauchy), so pixels of a
neighbour or of the web that entered the box do not pull the estimate.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass, replace

import cv2
import numpy as np


@dataclass(frozen=True)
class Farneback:
    """`cv2.calcOpticalFlowFarneback`'s settings, in its argument order."""

    pyr_scale: float = 0.5
    levels: int = 0
    winsize: int = 7
    iterations: int = 1
    poly_n: int = 5
    poly_sigma: float = 1.1
    flags: int = 0


#: Farnebäck settings for residuals under a pixel: one level, a small window, one iteration
#: (on the 1920x1200 benchmark a second iteration or a 9 px window changed no error by 0.01 mm
#: and cost 20 % of the speed).
FARNEBACK = Farneback()
#: Farnebäck settings for whole frame-to-frame motions (several px): a pyramid, a wider window.
FARNEBACK_LARGE = replace(FARNEBACK, levels=2, winsize=15, iterations=3)
#: Cauchy scale (px) of the robust second pass.
ROBUST_SCALE_PX = 0.5


def rotation_px(theta: float) -> np.ndarray:
    """2x2 rotation in pixel coordinates (v down) of a world rotation theta (CCW, z up)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, s], [-s, c]])


def warp_to_reference(image: np.ndarray, centre: tuple[float, float], theta: float,
                      ref_centre: tuple[float, float], size: tuple[int, int],
                      margin: int = 0) -> np.ndarray:
    """The current `image` resampled into the reference patch's coordinates (plus `margin` px on
    every side): reference point q lands on centre + R(theta) (q - ref_centre)."""
    w, h = size
    rot = rotation_px(theta)
    shift = np.asarray(centre) - rot @ (np.asarray(ref_centre) + margin)
    m = np.hstack([rot, shift[:, None]])
    return cv2.warpAffine(image, m, (w + 2 * margin, h + 2 * margin),
                          flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE)


def texture_weights(patch: np.ndarray, border: int) -> np.ndarray:
    """Per-pixel weight of a reference patch: smallest structure-tensor eigenvalue, zero within
    `border` px of the edge (Farnebäck's window reaches outside the box there)."""
    w = cv2.cornerMinEigenVal(patch, blockSize=5, ksize=3).astype(np.float32)
    mask = np.zeros_like(w)
    mask[border:-border or None, border:-border or None] = 1.0
    return w * mask


@dataclass(frozen=True)
class RigidMotion:
    """Residual motion of a patch: translation (px, image axes) and rotation (rad, world CCW)."""

    du: float
    dv: float
    dtheta: float


class RigidFlow:
    """The rigid fit of the flow between one reference patch and warped current patches; the
    pixel grid and its moments are computed once per object."""

    def __init__(self, reference: np.ndarray, ref_centre: tuple[float, float], border: int = 6,
                 farneback: Farneback = FARNEBACK) -> None:
        self.reference = reference
        self.farneback = astuple(farneback)
        h, w = reference.shape
        #: Farnebäck's output, reused: an object's flow is measured on one thread at a time
        self.flow = np.zeros((h, w, 2), np.float32)
        ys, xs = np.mgrid[0:h, 0:w].astype(np.float32)
        self.du = xs - np.float32(ref_centre[0])
        self.dv = ys - np.float32(ref_centre[1])
        self.weights = texture_weights(reference, border)
        if not np.any(self.weights > 0):
            raise ValueError("reference patch has no texture to follow")

    def measure(self, warped: np.ndarray) -> RigidMotion:
        """Fit translation + rotation to Farnebäck's flow from the reference to `warped`."""
        flow = cv2.calcOpticalFlowFarneback(self.reference, warped, self.flow, *self.farneback)
        fu, fv = flow[..., 0], flow[..., 1]
        motion = self._fit(fu, fv, self.weights)
        ru = fu - (motion.du + motion.dtheta * self.dv)
        rv = fv - (motion.dv - motion.dtheta * self.du)
        robust = self.weights / (1.0 + (ru * ru + rv * rv) / ROBUST_SCALE_PX**2)
        return self._fit(fu, fv, robust)

    def _fit(self, fu: np.ndarray, fv: np.ndarray, w: np.ndarray) -> RigidMotion:
        """Weighted least squares of f_u = tu + a dv, f_v = tv - a du (a: small rotation)."""
        du, dv = self.du, self.dv
        sw = float(w.sum())
        su, sv = float((w * du).sum()), float((w * dv).sum())
        srr = float((w * (du * du + dv * dv)).sum())
        bu, bv = float((w * fu).sum()), float((w * fv).sum())
        ba = float((w * (fu * dv - fv * du)).sum())
        a = np.array([[sw, 0.0, sv], [0.0, sw, -su], [sv, -su, srr]])
        tu, tv, rot = np.linalg.solve(a, [bu, bv, ba])
        return RigidMotion(float(tu), float(tv), float(rot))

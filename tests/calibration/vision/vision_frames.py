"""Frames with known motion for the vision tests: textured patches moved by exact sub-pixel
translations and rotations (cv2.warpAffine), plus noise."""

from __future__ import annotations

import cv2
import numpy as np


def texture(height: int, width: int, seed: int = 0, blur: float = 1.5) -> np.ndarray:
    """Blurred noise with stripes: texture at several scales, as a printed bundle face has."""
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.random((height, width)).astype(np.float32), (0, 0), blur)
    img = (img - img.min()) / (np.ptp(img) + 1e-9)
    return (40 + 180 * img).astype(np.uint8)


def moved(image: np.ndarray, centre: tuple[float, float], du: float, dv: float,
          theta: float = 0.0, noise: float = 2.0, seed: int = 1) -> np.ndarray:
    """`image` with the content rotated by theta (world CCW) about `centre` and shifted by
    (du, dv) px, plus Gaussian noise."""
    c, s = np.cos(theta), np.sin(theta)
    rot = np.array([[c, s], [-s, c]])
    cu, cv_ = centre
    shift = np.array([cu + du, cv_ + dv]) - rot @ np.array([cu, cv_])
    out = cv2.warpAffine(image, np.hstack([rot, shift[:, None]]), image.shape[1::-1],
                         flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    rng = np.random.default_rng(seed)
    return np.clip(out + rng.normal(0, noise, out.shape), 0, 255).astype(np.uint8)

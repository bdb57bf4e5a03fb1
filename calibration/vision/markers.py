"""ArUco markers: where the wrapped layers are, and a check of the camera's scale.

On a wrapped unit the web hides the bundles, so (as in the paper) layer positions come from
markers printed on the web; two markers on the sled give its position and, through their known
printed size, an independent measure of px_per_m.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from calibration.vision.roi import PixelMap
from calibration.vision.tracking import Frame

#: Relative disagreement of the markers' scale with setup.toml's px_per_m that gets a warning.
SCALE_TOLERANCE = 0.02


def dictionary(name: str) -> cv2.aruco.Dictionary:
    """A predefined ArUco dictionary by its OpenCV name ("DICT_4X4_50"); ValueError if unknown."""
    if not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise ValueError(f"unknown ArUco dictionary {name!r}")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


class MarkerDetector:
    """ArUco detection with sub-pixel corners, run on a frame crop (the region of interest)."""

    def __init__(self, dictionary_name: str) -> None:
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        params.cornerRefinementWinSize = 3
        self.detector = cv2.aruco.ArucoDetector(dictionary(dictionary_name), params)

    def detect(self, frame: Frame) -> dict[int, np.ndarray]:
        """Corners (4, 2) per marker id in full-frame pixels, in ArUco's order (top-left first,
        clockwise in the image); an id seen twice is dropped as ambiguous."""
        corners, ids, _ = self.detector.detectMarkers(frame.gray)
        if ids is None:
            return {}
        found: dict[int, np.ndarray] = {}
        seen: set[int] = set()
        for c, i in zip(corners, ids.ravel(), strict=True):
            i = int(i)
            if i in seen:
                found.pop(i, None)
                continue
            seen.add(i)
            found[i] = c.reshape(4, 2).astype(float) + (frame.x0, frame.y0)
        return found


def centre_px(corners: np.ndarray) -> np.ndarray:
    """A marker's centre: the mean of its corners (exact under the orthographic camera)."""
    return corners.mean(axis=0)


def angle_rad(corners: np.ndarray) -> float:
    """Rotation of a marker from upright, world convention (counter-clockwise, z up): the mean
    direction of its top and bottom edges."""
    edge = (corners[1] - corners[0]) + (corners[2] - corners[3])
    return float(np.arctan2(-edge[1], edge[0]))


def side_px(corners: np.ndarray) -> float:
    """Mean length of a marker's four sides in pixels."""
    return float(np.mean(np.linalg.norm(corners - np.roll(corners, -1, axis=0), axis=1)))


def scale_warning(sides_px: Sequence[float], size_m: float, px_per_m: float) -> str | None:
    """A warning when the markers' median scale (side px / size_m) disagrees with px_per_m."""
    if not sides_px:
        return None
    measured = float(np.median(sides_px)) / size_m
    if abs(measured / px_per_m - 1) <= SCALE_TOLERANCE:
        return None
    return (f"markers measure {measured:.1f} px/m but setup.toml camera.px_per_m is "
            f"{px_per_m:.1f} ({100 * (measured / px_per_m - 1):+.1f} %): positions use setup.toml")


@dataclass(frozen=True)
class ObjectPose:
    x_m: float
    z_m: float
    angle_rad: float


def object_pose(observations: Sequence[tuple[np.ndarray, tuple[float, float]]],
                pixmap: PixelMap) -> ObjectPose:
    """An object's centre and rotation from its markers: each marker's centre minus its offset
    (marker centre minus object centre, object frame at rest) rotated by the marker's angle,
    averaged over the markers seen (angles averaged as unit vectors)."""
    angles = np.array([angle_rad(c) for c, _ in observations])
    theta = float(np.arctan2(np.sin(angles).mean(), np.cos(angles).mean()))
    cos, sin = np.cos(theta), np.sin(theta)
    xs, zs = [], []
    for corners, (dx, dz) in observations:
        x, z = pixmap.to_world(*centre_px(corners))
        xs.append(x - (cos * dx - sin * dz))
        zs.append(z - (sin * dx + cos * dz))
    return ObjectPose(float(np.mean(xs)), float(np.mean(zs)), theta)

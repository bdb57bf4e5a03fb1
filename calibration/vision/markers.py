"""ArUco markers: where the wrapped layers are, and a check of the camera's scale.

On a wrapped unit the web hides the bundles, so (as in the paper) layer positions come from
markers printed on the web: ArUco names the objects, the patch tracker follows the markers
(`calibration.track`). Two markers on the sled give its position and, through the known distance
between them (hundreds of pixels, so a fraction of a pixel on their centres is a few 0.01 %), an
independent measure of px_per_m; a marker's own side is too short for that (a 0.5 px bias on
18 px is 3 %).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from calibration.vision.tracking import Frame

#: Relative disagreement of the markers' scale with setup.toml's px_per_m that gets a warning.
SCALE_TOLERANCE = 0.01
#: Relative disagreement of the markers' sides in the image with setup.toml's markers.size_m
#: that gets a warning: a side is too short to measure the scale (see above), but this catches
#: a size or scale off by a unit or a wrong print (a few pixels' blur and corner bias stay well
#: under it).
SIZE_TOLERANCE = 0.2


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
        for c, raw_id in zip(corners, ids.ravel(), strict=True):
            i = int(raw_id)
            if i in seen:
                found.pop(i, None)
                continue
            seen.add(i)
            found[i] = c.reshape(4, 2).astype(float) + (frame.x0, frame.y0)
        return found


def centre_px(corners: np.ndarray) -> np.ndarray:
    """A marker's centre: the mean of its corners (exact under the orthographic camera)."""
    return corners.mean(axis=0)


def side_px(corners: np.ndarray) -> float:
    """A marker's side in the image: the mean length of its four edges."""
    return float(np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1).mean())


def angle_rad(corners: np.ndarray) -> float:
    """Rotation of a marker from upright, world convention (counter-clockwise, z up): the mean
    direction of its top and bottom edges."""
    edge = (corners[1] - corners[0]) + (corners[2] - corners[3])
    return float(np.arctan2(-edge[1], edge[0]))


def baseline_scale(found: dict[int, np.ndarray],
                   offsets_m: dict[int, tuple[float, float]]) -> float | None:
    """px/m from the two farthest-apart markers of one rigid object (the sled) seen in a frame:
    their centres' distance in pixels over their placements' distance; None with fewer than two."""
    ids = [i for i in offsets_m if i in found]
    pairs = [(a, b) for k, a in enumerate(ids) for b in ids[k + 1:]]
    if not pairs:
        return None
    a, b = max(pairs, key=lambda p: math.dist(offsets_m[p[0]], offsets_m[p[1]]))
    distance_m = math.dist(offsets_m[a], offsets_m[b])
    if distance_m <= 0:
        return None
    return float(np.linalg.norm(centre_px(found[a]) - centre_px(found[b]))) / distance_m


def scale_warning(measured_px_per_m: float | None, px_per_m: float) -> str | None:
    """A warning when the markers' scale disagrees with setup.toml's px_per_m beyond
    `SCALE_TOLERANCE`."""
    if measured_px_per_m is None or abs(measured_px_per_m / px_per_m - 1) <= SCALE_TOLERANCE:
        return None
    return (f"the sled's markers measure {measured_px_per_m:.1f} px/m but setup.toml "
            f"camera.px_per_m is {px_per_m:.1f} ({100 * (measured_px_per_m / px_per_m - 1):+.1f} "
            "%): positions use setup.toml")


def size_warning(size_m: float | None, px_per_m: float, sides_px: list[float]) -> str | None:
    """A warning when setup.toml's markers.size_m cannot cross-check the scale (not given), or
    when at its scale it disagrees with the sides ArUco measures (`sides_px`, none: nothing
    to compare) beyond `SIZE_TOLERANCE`."""
    if size_m is None:
        return ("setup.toml gives no markers.size_m: the markers' sides cannot cross-check the "
                "scale (camera.px_per_m)")
    if not sides_px:
        return None
    expected, measured = size_m * px_per_m, float(np.median(sides_px))
    if abs(measured / expected - 1) <= SIZE_TOLERANCE:
        return None
    return (f"setup.toml's markers.size_m ({size_m:g} m) at camera.px_per_m ({px_per_m:g}) is "
            f"{expected:.1f} px, but ArUco measures the markers' sides {measured:.1f} px in "
            f"frame 0 ({100 * (measured / expected - 1):+.0f} %): is the size or the scale "
            "wrong?")


@dataclass(frozen=True)
class ObjectPose:
    x_m: float
    z_m: float
    angle_rad: float


def rigid_pose(centres_m: Sequence[tuple[float, float]], offsets_m: Sequence[tuple[float, float]],
               theta: float) -> ObjectPose:
    """An object's centre and rotation from its markers' world centres: with one marker the
    rotation is `theta` (measured on the marker itself), with more the rotation that best maps
    the offsets onto the centres (2-D Procrustes: a baseline of many pixels fixes it far better
    than one small marker does); the centre is then the markers' mean minus the rotated mean
    offset."""
    p, o = np.asarray(centres_m, float), np.asarray(offsets_m, float)
    if len(p) > 1:
        pc, oc = p - p.mean(axis=0), o - o.mean(axis=0)
        theta = float(np.arctan2(np.sum(oc[:, 0] * pc[:, 1] - oc[:, 1] * pc[:, 0]),
                                 np.sum(oc * pc)))
    cos, sin = np.cos(theta), np.sin(theta)
    ox, oz = o.mean(axis=0)
    x, z = p.mean(axis=0)
    return ObjectPose(float(x - (cos * ox - sin * oz)), float(z - (sin * ox + cos * oz)), theta)

"""ArUco: marker centres, angles and object poses in world metres; the scale check."""

import cv2
import numpy as np

from calibration.vision.markers import (
    MarkerDetector,
    angle_rad,
    object_pose,
    scale_warning,
    side_px,
)
from calibration.vision.roi import PixelMap
from calibration.vision.tracking import Frame

PIXMAP = PixelMap(400.0, 100.0, 350.0)


def _scene(theta: float, centre: tuple[float, float], side: int = 40) -> np.ndarray:
    """Marker 7 of DICT_4X4_50 with a white border, rotated by theta (world CCW) about its
    centre placed at `centre` (px) in a grey image."""
    marker = cv2.aruco.generateImageMarker(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), 7, side)
    tile = cv2.copyMakeBorder(marker, side // 2, side // 2, side // 2, side // 2,
                              cv2.BORDER_CONSTANT, value=255)
    image = np.full((400, 600), 128, np.uint8)
    c, s = np.cos(theta), np.sin(theta)
    rot = np.array([[c, s], [-s, c]])
    tc = np.array([(tile.shape[1] - 1) / 2, (tile.shape[0] - 1) / 2])
    m = np.hstack([rot, (np.array(centre) - rot @ tc)[:, None]])
    warped = cv2.warpAffine(tile, m, (600, 400), flags=cv2.INTER_CUBIC, borderValue=128)
    mask = cv2.warpAffine(np.ones_like(tile), m, (600, 400), flags=cv2.INTER_NEAREST)
    image[mask > 0] = warped[mask > 0]
    return image


def test_marker_centre_angle_and_side() -> None:
    image = _scene(0.1, (300.0, 200.0))
    found = MarkerDetector("DICT_4X4_50").detect(Frame(image[100:, 150:], 150, 100))
    corners = found[7]
    # marker pixel (c, r) covers [c - 0.5, c + 0.5]: a 40 px tile's centre is at 19.5
    assert np.allclose(corners.mean(axis=0), (300.0, 200.0), atol=0.3)
    assert abs(angle_rad(corners) - 0.1) < 0.01
    assert abs(side_px(corners) - 40) < 0.5


def test_object_pose_subtracts_the_rotated_offset() -> None:
    """A marker 0.1 m right of its object's centre, object turned 90 degrees CCW: the marker is
    then 0.1 m above the centre."""
    u, v = PIXMAP.to_px(1.0, 0.6)
    side = 10.0
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * side / 2
    turned = square @ np.array([[0.0, 1.0], [-1.0, 0.0]]).T  # 90 deg CCW in world terms
    pose = object_pose([(turned + (u, v), (0.1, 0.0))], PIXMAP)
    assert abs(pose.angle_rad - np.pi / 2) < 1e-9
    assert abs(pose.x_m - 1.0) < 1e-9 and abs(pose.z_m - 0.5) < 1e-9


def test_scale_warning_beyond_two_percent() -> None:
    assert scale_warning([40.4, 39.8], 0.1, 400.0) is None
    message = scale_warning([42.0, 42.2], 0.1, 400.0)
    assert message is not None and "+5.2 %" in message

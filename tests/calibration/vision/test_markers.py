"""ArUco: marker centres, angles and object poses in world metres; the scale check."""

import cv2
import numpy as np

from calibration.vision.markers import (
    MarkerDetector,
    angle_rad,
    baseline_scale,
    rigid_pose,
    scale_warning,
    size_warning,
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


def test_rigid_pose_takes_the_rotation_from_two_markers() -> None:
    """Two markers 1 m apart on an object turned 0.02 rad about (2.0, 0.3): the given rotation
    (one marker's own, noisy) is overruled by the baseline's."""
    c, s = np.cos(0.02), np.sin(0.02)
    offsets = [(-0.5, 0.1), (0.5, 0.1)]
    centres = [(2.0 + c * dx - s * dz, 0.3 + s * dx + c * dz) for dx, dz in offsets]
    pose = rigid_pose(centres, offsets, theta=0.3)
    assert abs(pose.angle_rad - 0.02) < 1e-12
    assert abs(pose.x_m - 2.0) < 1e-12 and abs(pose.z_m - 0.3) < 1e-12
    one = rigid_pose(centres[:1], offsets[:1], theta=0.02)
    assert abs(one.x_m - 2.0) < 1e-12 and abs(one.z_m - 0.3) < 1e-12


def test_baseline_scale_from_the_farthest_markers() -> None:
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * 5
    found = {0: square + (100.0, 50.0), 1: square + (700.0, 50.0), 5: square + (400.0, 50.0)}
    offsets = {0: (-1.0, 0.0), 1: (1.0, 0.0), 5: (0.0, 0.0), 9: (3.0, 0.0)}
    assert baseline_scale(found, offsets) == 300.0
    assert baseline_scale({0: found[0]}, offsets) is None


def test_scale_warning_beyond_one_percent() -> None:
    assert scale_warning(None, 400.0) is None
    assert scale_warning(403.0, 400.0) is None
    message = scale_warning(412.0, 400.0)
    assert message is not None and "+3.0 %" in message


def test_rigid_pose_of_three_markers_placed_off_centre() -> None:
    """Markers at offsets whose mean is off the object's centre, the object turned 0.3 rad
    about (1.5, 0.7) m: its centre and rotation come back exactly."""
    c, s = np.cos(0.3), np.sin(0.3)
    offsets = [(-0.4, 0.2), (0.3, 0.25), (0.1, -0.3)]
    centres = [(1.5 + c * dx - s * dz, 0.7 + s * dx + c * dz) for dx, dz in offsets]
    pose = rigid_pose(centres, offsets, theta=0.0)
    assert abs(pose.angle_rad - 0.3) < 1e-12
    assert abs(pose.x_m - 1.5) < 1e-12 and abs(pose.z_m - 0.7) < 1e-12


def test_a_marker_s_angle_is_the_mean_direction_of_its_top_and_bottom_edges() -> None:
    """Corners as ArUco gives them (top-left, top-right, bottom-right, bottom-left; v down): a
    top edge rising 1 px over 10 and a bottom edge rising 3 px over 10 turn 0.2 rad
    counter-clockwise (arctan of 4 / 20)."""
    corners = np.array([[0.0, 0.0], [10.0, -1.0], [10.0, 7.0], [0.0, 10.0]])
    assert abs(angle_rad(corners) - np.arctan2(4.0, 20.0)) < 1e-12


def test_the_scale_is_read_from_the_farthest_pair_wherever_it_comes_in_the_list() -> None:
    """Marker 5's centre lies 2 px off (a pair with it would read 302 or 298 px/m); the
    farthest pair, 0 and 1 two metres apart, reads 300. Two markers at one offset give none."""
    square = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float) * 5
    found = {0: square + (100.0, 50.0), 1: square + (700.0, 50.0), 5: square + (402.0, 50.0)}
    offsets = {5: (0.0, 0.0), 0: (-1.0, 0.0), 1: (1.0, 0.0)}
    assert baseline_scale(found, offsets) == 300.0
    assert baseline_scale(found, {0: (0.5, 0.0), 1: (0.5, 0.0)}) is None


def test_the_marker_size_cross_checks_the_scale_within_twenty_percent() -> None:
    """5 cm markers at 400 px/m should measure 20 px a side: a median of 23 px (+15 %) passes,
    25 px (+25 %) and 15 px (-25 %) are said with both figures; without a size nothing can be
    checked (said), and without a marker seen nothing is compared."""
    assert size_warning(0.05, 400.0, [22.0, 23.0, 40.0]) is None
    high = size_warning(0.05, 400.0, [24.0, 25.0, 26.0])
    assert high is not None and "20.0 px" in high and "25.0 px" in high and "+25 %" in high
    low = size_warning(0.05, 400.0, [15.0])
    assert low is not None and "15.0 px" in low and "-25 %" in low
    assert size_warning(0.05, 400.0, []) is None
    missing = size_warning(None, 400.0, [25.0])
    assert missing is not None and "no markers.size_m" in missing

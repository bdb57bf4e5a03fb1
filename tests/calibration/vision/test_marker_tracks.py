"""A wrapped unit's objects followed through the markers on its web: a marker hidden for a few
frames is reported lost, found again by ArUco, and the object's path bridged across the gap;
a marker that comes into view late, or whose box does not fit in the frame at first, is
followed from there, on an object already turned with the turn of a marker followed before
it (in frame 0, at rest); ArUco only cross-checks the followed marker, and a disagreement is
reported."""

from collections.abc import Callable

import cv2
import numpy as np
import pytest

from calibration import opencv_threads
from calibration.camera_setup import MarkerPlacement
from calibration.vision.marker_tracks import MARKER_CHECK_PX, MarkerTracks
from calibration.vision.markers import MarkerDetector
from calibration.vision.roi import PixelMap
from calibration.vision.tracking import LOST_SCORE, Frame, MultiTracker
from tests.calibration.vision.vision_frames import texture

PIXMAP = PixelMap(400.0, 100.0, 350.0)
FRAMES, FPS = 14, 20.0
START_U, STEP_U, V = 200.0, 3.0, 200.0   # the marker's centre (px) and its motion per frame
SIDE = 40                                # the marker's side, px


def _tile(marker_id: int) -> np.ndarray:
    """The printed marker with a white quiet zone half its side wide."""
    marker = cv2.aruco.generateImageMarker(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), marker_id, SIDE)
    h = SIDE // 2
    return cv2.copyMakeBorder(marker, h, h, h, h, cv2.BORDER_CONSTANT, value=255)


def _frame(k: int, hidden: bool, start_u: float = START_U, step_u: float = STEP_U) -> np.ndarray:
    """Frame k: marker 7 on a printed background, its centre at start_u + step_u k; `hidden`:
    a fold of the web covers it (the background drawn over it)."""
    image = texture(400, 600, seed=3)
    if not hidden:
        tile = _tile(7)
        shift = np.array([[1, 0, start_u + step_u * k - (tile.shape[1] - 1) / 2],
                          [0, 1, V - (tile.shape[0] - 1) / 2]], np.float32)
        warped = cv2.warpAffine(tile, shift, (600, 400), flags=cv2.INTER_CUBIC)
        mask = cv2.warpAffine(np.ones_like(tile), shift, (600, 400), flags=cv2.INTER_NEAREST)
        image[mask > 0] = warped[mask > 0]
    return image


class _ShiftedDetector(MarkerDetector):
    """ArUco whose corners in frame `index` come out `shift_px` to the right (`now`: the frame
    being tracked)."""

    def __init__(self, index: int, shift_px: float) -> None:
        super().__init__("DICT_4X4_50")
        self.index, self.shift_px, self.now = index, shift_px, 0

    def detect(self, frame: Frame) -> dict[int, np.ndarray]:
        found = super().detect(frame)
        shift = [self.shift_px, 0.0] if self.now == self.index else [0.0, 0.0]
        return {i: c + shift for i, c in found.items()}


def _drive(placements: list[MarkerPlacement], detector: MarkerDetector,
           image: Callable[[int], np.ndarray]) -> tuple[MarkerTracks, list[str]]:
    """Frames 0..FRAMES-1 (`image(k)`) through MarkerTracks as `track` drives it (OpenCV on one
    thread, the sled not moving)."""
    warnings: list[str] = []
    multi = MultiTracker({}, {}, threads=1)
    markers = MarkerTracks(placements, None, detector, multi, PIXMAP, warnings)
    with opencv_threads(1):
        for k in range(FRAMES):
            frame = Frame(image(k))
            if isinstance(detector, _ShiftedDetector):
                detector.now = k
            if k == 0:
                markers.start(frame, detector.detect(frame), 0.0)
            else:
                markers.step(k, frame, 0.0, multi.step(frame, 0.0))
    multi.close()
    return markers, warnings


def _follow(hidden: set[int], start_u: float = START_U, step_u: float = STEP_U,
            detector: MarkerDetector | None = None,
            stops_after: int = FRAMES) -> tuple[MarkerTracks, list[str]]:
    """Marker 7 on object L1C1R1 through the frames; it stays where it is in frame
    `stops_after` from then on."""
    return _drive([MarkerPlacement(7, "L1C1R1", (0.05, 0.10))],
                  detector or MarkerDetector("DICT_4X4_50"),
                  lambda k: _frame(min(k, stops_after), k in hidden, start_u, step_u))


def _true_x_m(k: np.ndarray, start_u: float = START_U) -> np.ndarray:
    """The object's centre: the marker's minus its placement offset."""
    return (start_u + STEP_U * k - PIXMAP.u0) / PIXMAP.px_per_m - 0.05


def test_a_marker_followed_throughout_gives_its_object_s_path() -> None:
    markers, warnings = _follow(hidden=set())
    path = markers.paths(FRAMES, FPS)["L1C1R1"]
    k = np.rint(path.t_s * FPS)
    assert np.array_equal(k, np.arange(FRAMES))
    assert np.max(np.abs(path.x_m - _true_x_m(k))) < 0.25 / PIXMAP.px_per_m
    assert np.max(np.abs(path.z_m - ((PIXMAP.v0 - V) / PIXMAP.px_per_m - 0.10))) < 1e-3
    assert markers.paths(FRAMES, FPS) and warnings == []


def test_a_hidden_marker_is_reported_lost_found_again_and_its_gap_bridged() -> None:
    """Covered in frames 5-7: the patch tracker scores below LOST_SCORE there, ArUco finds the
    marker again in frame 8 (it is looked for in every frame a marker is lost), and the path
    is interpolated over 5-7 with both facts warned about."""
    markers, warnings = _follow(hidden={5, 6, 7})
    assert markers.lost[7] == [5, 6, 7]
    path = markers.paths(FRAMES, FPS)["L1C1R1"]
    k = np.rint(path.t_s * FPS)
    assert np.array_equal(k, np.arange(FRAMES))
    # moving uniformly, the bridged frames lie on the line through their neighbours
    assert np.max(np.abs(path.x_m - _true_x_m(k))) < 0.25 / PIXMAP.px_per_m
    assert warnings == [
        f"marker 7 (L1C1R1): lost (NCC < {LOST_SCORE}) in frames 5-7",
        "L1C1R1: no marker followed in 3 frames (frames 5-7 interpolated)"]


@pytest.mark.parametrize("step_u, hidden", [(3.0, {5, 6, 7}), (6.0, {5, 6, 7, 8, 9})])
def test_a_marker_that_stopped_while_hidden_is_found_where_it_stopped(
        step_u: float, hidden: set[int]) -> None:
    """Covered after moving `step_u` px a frame, it stopped where it was in frame 4; its
    prediction runs on past it. 12 px past (3 px a frame, 3 frames), the patch tracker's
    search walks on from its window's edge and finds it (taken from the edge it was 1.2 px
    off, and the bridged frames with it); 36 px past (6 px, 5 frames), the tracker loses it and
    ArUco, looking for it because it is lost, finds it. Either way its path is right to a
    quarter of a pixel, the hidden frames bridged."""
    markers, warnings = _follow(hidden=hidden, step_u=step_u, stops_after=4)
    assert markers.lost[7] == sorted(hidden)
    path = markers.paths(FRAMES, FPS)["L1C1R1"]
    k = np.rint(path.t_s * FPS)
    assert np.array_equal(k, np.arange(FRAMES))
    truth = (START_U + step_u * np.minimum(k, 4) - PIXMAP.u0) / PIXMAP.px_per_m - 0.05
    assert np.max(np.abs(path.x_m - truth)) < 0.25 / PIXMAP.px_per_m
    gap = f"{min(hidden)}-{max(hidden)}"
    assert warnings == [
        f"marker 7 (L1C1R1): lost (NCC < {LOST_SCORE}) in frames {gap}",
        f"L1C1R1: no marker followed in {len(hidden)} frames (frames {gap} interpolated)"]


@pytest.mark.parametrize("hidden,text", [({0, 1, 2}, "frames 0-2 left out"),
                                         ({11, 12, 13}, "frames 11-13 left out")])
def test_frames_before_a_marker_is_first_seen_or_after_it_is_last_seen_are_left_out(
        hidden: set[int], text: str) -> None:
    """A marker first seen in frame 3 is followed from there (ArUco looks for an unseen marker
    in every frame); one covered from frame 11 on is lost to the end. Either way the path
    covers only the frames it was seen in."""
    markers, warnings = _follow(hidden=hidden)
    path = markers.paths(FRAMES, FPS)["L1C1R1"]
    k = np.rint(path.t_s * FPS)
    assert np.array_equal(k, np.array(sorted(set(range(FRAMES)) - hidden)))
    assert np.max(np.abs(path.x_m - _true_x_m(k))) < 0.25 / PIXMAP.px_per_m
    assert warnings[-1] == f"L1C1R1: no marker followed in 3 frames ({text})"


def test_a_marker_whose_box_leaves_the_frame_is_followed_once_the_box_fits() -> None:
    """Detected 30 px from the frame's left edge, where its 64 px box (and the flow's pad) does
    not fit: looked for again in each frame, and followed from frame 3, where it does."""
    markers, warnings = _follow(hidden=set(), start_u=30.0)
    path = markers.paths(FRAMES, FPS)["L1C1R1"]
    k = np.rint(path.t_s * FPS)
    assert np.array_equal(k, np.arange(3, FRAMES))
    assert np.max(np.abs(path.x_m - _true_x_m(k, start_u=30.0))) < 0.25 / PIXMAP.px_per_m
    assert warnings == [
        "marker 7 (L1C1R1): detected where its box leaves the frame in frames 0-2, not "
        "followed there",
        "L1C1R1: no marker followed in 3 frames (frames 0-2 left out)"]


def test_a_marker_whose_box_never_fits_leaves_its_object_untracked_and_says_why() -> None:
    markers, warnings = _follow(hidden=set(), start_u=30.0, step_u=0.0)
    assert markers.paths(FRAMES, FPS) == {}
    assert warnings == [
        f"marker 7 (L1C1R1): detected where its box leaves the frame in frames 0-{FRAMES - 1}, "
        "not followed there",
        "L1C1R1: markers [7] never followed; not tracked"]


def test_a_marker_never_detected_is_reported_so() -> None:
    markers, warnings = _follow(hidden=set(range(FRAMES)))
    assert markers.paths(FRAMES, FPS) == {}
    assert warnings == ["L1C1R1: markers [7] never detected; not tracked"]


def test_aruco_only_cross_checks_a_followed_marker() -> None:
    """In a check frame (10) ArUco's corners come out 3 px off: the frames are reported, and
    the path keeps the patch tracker's sub-pixel pose."""
    markers, warnings = _follow(hidden=set(), detector=_ShiftedDetector(index=10, shift_px=3.0))
    assert markers.disagree[7] == [10]
    path = markers.paths(FRAMES, FPS)["L1C1R1"]
    k = np.rint(path.t_s * FPS)
    assert np.max(np.abs(path.x_m - _true_x_m(k))) < 0.25 / PIXMAP.px_per_m
    assert warnings == [f"marker 7 (L1C1R1): followed and ArUco-detected centres differ by "
                        f"more than {MARKER_CHECK_PX} px in frames 10"]


CARD_CENTRE_PX, CARD_TURN_DEG = (300.0, 200.0), 1.5   # a card turning 1.5 degrees a frame
CARD_MARKERS = {7: ((-0.15, 0.0), range(2, 10)), 8: ((0.15, 0.0), range(5, FRAMES))}


def _card_frame(k: int) -> np.ndarray:
    """Frame k of a card carrying markers 7 and 8 (offsets and the frames each is uncovered
    in: CARD_MARKERS), turned counter-clockwise by CARD_TURN_DEG k about its centre."""
    image = texture(400, 600, seed=3)
    turn = np.vstack([cv2.getRotationMatrix2D(CARD_CENTRE_PX, CARD_TURN_DEG * k, 1.0),
                      [0.0, 0.0, 1.0]])
    for marker_id, ((x_m, z_m), seen) in CARD_MARKERS.items():
        if k not in seen:
            continue
        tile = _tile(marker_id)
        u = CARD_CENTRE_PX[0] + x_m * PIXMAP.px_per_m - (tile.shape[1] - 1) / 2
        v = CARD_CENTRE_PX[1] - z_m * PIXMAP.px_per_m - (tile.shape[0] - 1) / 2
        placed = (turn @ np.array([[1.0, 0.0, u], [0.0, 1.0, v], [0.0, 0.0, 1.0]]))[:2]
        warped = cv2.warpAffine(tile, placed.astype(np.float32), (600, 400),
                                flags=cv2.INTER_CUBIC)
        mask = cv2.warpAffine(np.ones_like(tile), placed.astype(np.float32), (600, 400),
                              flags=cv2.INTER_NEAREST)
        image[mask > 0] = warped[mask > 0]
    return image


class _SkewedFirstDetector(MarkerDetector):
    """ArUco whose corners of marker `marker_id` come out turned 2 degrees further than the
    marker is, the first time it is found: a small marker's edges give a noisy angle."""

    def __init__(self, marker_id: int) -> None:
        super().__init__("DICT_4X4_50")
        self.marker_id, self.skewed = marker_id, False

    def detect(self, frame: Frame) -> dict[int, np.ndarray]:
        found = super().detect(frame)
        if self.marker_id in found and not self.skewed:
            self.skewed = True
            a = np.radians(2.0)                        # counter-clockwise seen, v pointing down
            turn = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
            corners = found[self.marker_id]
            mid = corners.mean(axis=0)
            found[self.marker_id] = (corners - mid) @ turn.T + mid
        return found


def test_a_marker_seen_in_the_first_frame_starts_at_rest_whatever_its_corners_say() -> None:
    """Placements are given at rest, so frame 0's rotation is zero, not what a small marker's
    corners (2 degrees off here) say; the path's rotation stays zero."""
    detector = _SkewedFirstDetector(7)
    markers, _ = _follow(hidden=set(), detector=detector)
    assert detector.skewed and markers.theta0[7] == 0.0
    path = markers.paths(FRAMES, FPS)["L1C1R1"]
    assert np.max(np.abs(np.degrees(path.angle_rad))) < 0.3


def test_a_marker_first_seen_on_a_turned_object_takes_the_turn_from_a_followed_marker() -> None:
    """Marker 7 is uncovered in frame 2, the card already turned 3 degrees (its rotation there
    from its own edges); marker 8 in frame 5, at 7.5 degrees, its ArUco corners 2 degrees off.
    Marker 8's starting rotation is marker 7's tracked turn since frame 2 plus 7's own start,
    not its corners'. That matters once 7 is covered (frames 10-13): the card's rotation is
    then marker 8's alone, and stays right to the 0.2 degrees of 7's edges in frame 2."""
    detector = _SkewedFirstDetector(8)
    placements = [MarkerPlacement(i, "card", offset) for i, (offset, _) in CARD_MARKERS.items()]
    markers, _ = _drive(placements, detector, _card_frame)
    assert detector.skewed and markers.lost[7] == [10, 11, 12, 13]
    assert abs(np.degrees(markers.theta0[8]) - 5 * CARD_TURN_DEG) < 0.3
    path = markers.paths(FRAMES, FPS)["card"]
    k = np.rint(path.t_s * FPS)
    assert np.array_equal(k, np.arange(2, FRAMES))
    assert np.max(np.abs(np.degrees(path.angle_rad) - CARD_TURN_DEG * k)) < 0.3
    centre_x_m = (CARD_CENTRE_PX[0] - PIXMAP.u0) / PIXMAP.px_per_m
    assert np.max(np.abs(path.x_m - centre_x_m)) < 0.5 / PIXMAP.px_per_m

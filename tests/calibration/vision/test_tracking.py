"""Patch tracking against the first frame: sub-pixel translation and rotation without drift."""

import numpy as np
import pytest

import calibration.vision.tracking
from calibration.vision.tracking import (
    LOST_SCORE,
    Frame,
    MultiTracker,
    PatchTracker,
    Pose,
    Reference,
    Tracker,
    check_tracker,
    make_tracker,
)
from tests.calibration.vision.vision_frames import moved, texture

CENTRE = (200.3, 150.6)
SIZE = (110, 130)


@pytest.mark.parametrize("du,dv,theta", [(0.37, -0.21, 0.0), (3.6, 2.2, 0.0),
                                         (-1.3, 0.8, 0.03), (6.0, -4.0, -0.05)])
def test_ncc_flow_recovers_motion(du: float, dv: float, theta: float) -> None:
    """One update from the unmoved pose; a rotation the prediction lacks takes a second update
    (in a recording, the next frame) to converge."""
    image = texture(300, 400)
    tracker = PatchTracker(Frame(image), CENTRE, SIZE)
    frame = Frame(moved(image, CENTRE, du, dv, theta))
    pose, score = tracker.update(frame, Pose(*CENTRE))
    assert score > 0.5  # a rotation the prediction lacks lowers the NCC peak
    if theta:
        pose, score = tracker.update(frame, pose)
    assert abs(pose.u - CENTRE[0] - du) < 0.05 and abs(pose.v - CENTRE[1] - dv) < 0.05
    assert abs(pose.theta - theta) < 2e-3


def test_crop_offset_is_accounted_for() -> None:
    image = texture(300, 400)
    tracker = PatchTracker(Frame(image[50:, 30:], 30, 50), CENTRE, SIZE)
    frame = moved(image, CENTRE, 1.25, -0.5)
    pose, _ = tracker.update(Frame(frame[40:, 20:], 20, 40), Pose(*CENTRE))
    assert abs(pose.u - CENTRE[0] - 1.25) < 0.05 and abs(pose.v - CENTRE[1] + 0.5) < 0.05


def test_no_drift_over_a_long_sequence() -> None:
    """A patch moving 0.3 px a frame for 100 frames ends within 0.1 px (chaining would not)."""
    image = texture(300, 400, seed=5)
    trackers: dict[str, Tracker] = {"a": PatchTracker(Frame(image), CENTRE, SIZE)}
    multi = MultiTracker(trackers, {"a": Pose(*CENTRE)}, threads=1)
    for k in range(1, 101):
        frame = moved(image, CENTRE, 0.3 * k, 0.0, noise=3.0, seed=k)
        pose, _ = multi.step(Frame(frame), sled_u=0.0)["a"]
    assert abs(pose.u - CENTRE[0] - 30.0) < 0.1 and abs(pose.v - CENTRE[1]) < 0.1


@pytest.mark.parametrize("jump_px", [3.0, 5.0])
def test_a_slide_starting_in_a_frame_that_skips_ncc_is_matched_again(jump_px: float) -> None:
    """ncc+flow skips NCC after a frame its prediction met. If the object then jumps from the
    prediction, one Farnebäck step alone left it 0.9 px (3 px jump) to 4 px (5 px) off; the
    frame is matched again from that result."""
    image = texture(300, 400, seed=5)
    tracker = PatchTracker(Frame(image), CENTRE, SIZE)
    tracker.update(Frame(moved(image, CENTRE, 0.0, 0.0, seed=2)), Pose(*CENTRE))
    assert tracker.predicted_well  # so the next frame's NCC is skipped
    pose, score = tracker.update(Frame(moved(image, CENTRE, jump_px, 0.0, seed=3)),
                                 Pose(*CENTRE))
    assert score > 0.9
    assert abs(pose.u - CENTRE[0] - jump_px) < 0.05 and abs(pose.v - CENTRE[1]) < 0.05
    assert not tracker.predicted_well  # the next frame searches too


@pytest.mark.parametrize("cover", ["plain", "printed"])
def test_an_object_covered_in_a_frame_that_skips_ncc_is_lost(cover: str) -> None:
    """Over a plain cover (a fold of paper over a marker) Farnebäck finds no motion and lands on
    the prediction, so a frame whose NCC was skipped kept the last NCC's score (0.996) and the
    object was followed by its extrapolated motion. Its result is scored by the reference:
    low, so the frame is searched again and the object lost."""
    image = texture(300, 400, seed=5)
    tracker = PatchTracker(Frame(image), CENTRE, SIZE)
    tracker.update(Frame(moved(image, CENTRE, 0.0, 0.0, seed=2)), Pose(*CENTRE))
    assert tracker.predicted_well  # so the next frame's NCC is skipped
    covered = np.full_like(image, 128) if cover == "plain" else texture(300, 400, seed=9)
    pose, score = tracker.update(Frame(covered), Pose(*CENTRE))
    assert score < LOST_SCORE and pose == Pose(*CENTRE)
    assert not tracker.predicted_well


@pytest.mark.parametrize("off_px", [8.5, 9.0, 10.0])
def test_an_object_just_beyond_the_search_window_is_found_where_it_is(off_px: float) -> None:
    """The NCC search looks 8 px either side of the prediction. An object 8.5-10 px away peaks
    on the window's edge, where the peak is not bracketed: the search goes on from there and
    finds it to 0.05 px (taken from the edge, 10 px came out 0.39 px off, scoring 0.64)."""
    image = texture(300, 400, seed=5)
    tracker = PatchTracker(Frame(image), CENTRE, SIZE)
    pose, score = tracker.update(Frame(moved(image, CENTRE, -off_px, 0.4)), Pose(*CENTRE))
    assert abs(pose.u - CENTRE[0] + off_px) < 0.05 and abs(pose.v - CENTRE[1] - 0.4) < 0.05
    assert score > 0.9


def test_an_object_whose_peak_stays_on_the_window_s_edge_is_lost_not_misplaced(
        monkeypatch) -> None:
    """With a single window allowed, an object 10 px away still peaks on its edge: it counts
    as not found (the prediction, score 0) instead of being reported at the edge."""
    monkeypatch.setattr(calibration.vision.tracking, "MAX_SEARCHES", 1)
    image = texture(300, 400, seed=5)
    tracker = PatchTracker(Frame(image), CENTRE, SIZE)
    assert tracker.update(Frame(moved(image, CENTRE, -10.0, 0.4)), Pose(*CENTRE)) == (
        Pose(*CENTRE), 0.0)


def test_sled_shift_drives_the_prediction() -> None:
    """An object carried 25 px by the sled is found although it is beyond the NCC search."""
    image = texture(300, 400, seed=6)
    multi = MultiTracker({"a": PatchTracker(Frame(image), CENTRE, SIZE)}, {"a": Pose(*CENTRE)})
    pose, score = multi.step(Frame(moved(image, CENTRE, 25.4, 0.0)), sled_u=25.0)["a"]
    multi.close()
    assert score > 0.8 and abs(pose.u - CENTRE[0] - 25.4) < 0.05


def test_lost_object_scores_low() -> None:
    image = texture(300, 400, seed=7)
    tracker = PatchTracker(Frame(image), CENTRE, SIZE)
    _, score = tracker.update(Frame(texture(300, 400, seed=8)), Pose(*CENTRE))
    assert score < 0.5


@pytest.mark.parametrize("kind", ["ncc", "flow", "chain", "mil"])
def test_other_trackers_follow_a_small_shift(kind: str) -> None:
    image = texture(300, 400, seed=9)
    tracker = make_tracker(kind, Frame(image), CENTRE, SIZE)
    pose, score = tracker.update(Frame(moved(image, CENTRE, 2.0, 1.0)), Pose(*CENTRE))
    tol = 1.0 if kind == "mil" else 0.1
    assert abs(pose.u - CENTRE[0] - 2.0) < tol and abs(pose.v - CENTRE[1] - 1.0) < tol
    assert score > (0.7 if kind == "mil" else 0.9)  # mil's whole pixels cost some NCC


@pytest.mark.parametrize("kind", ["ncc+flow", "ncc", "flow", "chain", "mil"])
def test_every_tracker_scores_a_frame_without_its_object_as_lost(kind: str) -> None:
    """The score is the first-frame patch's NCC at the pose reported: where the object is not,
    it is under LOST_SCORE and the pose is the prediction. flow, chain and mil used to score
    1.0 whatever they reported, so lost objects were written as found."""
    image = texture(300, 400, seed=7)
    tracker = make_tracker(kind, Frame(image), CENTRE, SIZE)
    predicted = Pose(CENTRE[0] + 1.0, CENTRE[1])
    pose, score = tracker.update(Frame(texture(300, 400, seed=8)), predicted)
    assert score < LOST_SCORE and pose == predicted


class _Drifting:
    """A tracker that finds its object 2 px right, 1 px down and 0.01 rad turned from where it
    was predicted, and records each prediction."""

    box_size = (20, 20)

    def __init__(self) -> None:
        self.predicted: list[Pose] = []

    def update(self, frame: Frame, predicted: Pose) -> tuple[Pose, float]:
        self.predicted.append(predicted)
        return Pose(predicted.u + 2.0, predicted.v + 1.0, predicted.theta + 0.01), 1.0


def test_each_object_is_predicted_from_the_sled_s_shift_and_its_own_last_motion() -> None:
    """Frame 1: the sled's 10 px alone (no motion of its own yet). Frame 2: the sled's further
    10 px plus the 2 px, 1 px and 0.01 rad the object moved on the sled in frame 1. An object
    first followed at a sled shift of 30 px is predicted from that shift on."""
    tracker = _Drifting()
    multi = MultiTracker({"a": tracker}, {"a": Pose(100.0, 50.0)}, threads=1)
    multi.step(Frame(np.zeros((4, 4), np.uint8)), sled_u=10.0)
    multi.step(Frame(np.zeros((4, 4), np.uint8)), sled_u=20.0)
    late = _Drifting()
    multi.add("b", late, Pose(300.0, 60.0), sled_u=30.0)
    multi.step(Frame(np.zeros((4, 4), np.uint8)), sled_u=35.0)
    assert tracker.predicted[:2] == [Pose(110.0, 50.0), Pose(124.0, 52.0, 0.02)]
    assert late.predicted == [Pose(305.0, 60.0)]


def test_a_retried_object_is_predicted_from_the_retry_s_result() -> None:
    """Lost in frame 1 and found again from a better prediction (200, 80): frame 2 is
    predicted from where the retry found it, moving as it moved since frame 0."""
    tracker = _Drifting()
    multi = MultiTracker({"a": tracker}, {"a": Pose(100.0, 50.0)}, threads=1)
    multi.step(Frame(np.zeros((4, 4), np.uint8)), sled_u=10.0)
    assert multi.retry("a", Frame(np.zeros((4, 4), np.uint8)), Pose(200.0, 80.0)) == (
        Pose(202.0, 81.0, 0.01), 1.0)
    multi.step(Frame(np.zeros((4, 4), np.uint8)), sled_u=20.0)
    # on the sled it moved 202 - 10 - 100 = 92 px in frame 1, and 31 px down
    assert tracker.predicted[-1] == Pose(202.0 - 10.0 + 20.0 + 92.0, 112.0, 0.02)


@pytest.mark.parametrize("crop", [(0, 0), (10, 5)])
@pytest.mark.parametrize("centre, fits", [((16.0, 14.0), True), ((83.0, 65.0), True),
                                          ((15.5, 14.0), False), ((16.0, 13.5), False),
                                          ((83.5, 65.0), False), ((83.0, 65.5), False)])
def test_an_object_s_box_and_its_pad_must_lie_within_the_frame(centre: tuple[float, float],
                                                               fits: bool,
                                                               crop: tuple[int, int]) -> None:
    """A 20 x 16 px box with the 6 px pad Farnebäck's window needs, in a 100 x 80 frame: centred
    on (16, 14) it touches the top-left corner, on (83, 65) the bottom-right (pixels 0-99 and
    0-79); half a pixel further it leaves the frame. A crop's corner is where the frame starts
    in the full image, in which centres are given."""
    frame = Frame(texture(80, 100), *crop)
    at = (centre[0] + crop[0], centre[1] + crop[1])
    if fits:
        assert PatchTracker(frame, at, (20, 16)).box_size == (21, 17)
    else:
        with pytest.raises(ValueError, match="leaves the frame"):
            PatchTracker(frame, at, (20, 16))


def test_ncc_flow_searches_only_after_a_frame_its_prediction_missed(monkeypatch) -> None:
    """An object carried by the sled alone (each prediction met): the NCC search runs in the
    first frame only, Farnebäck alone follows it after; the other trackers' choice of search is
    fixed (ncc always, flow never)."""
    image = texture(300, 400, seed=5)
    searches = {kind: 0 for kind in ("ncc+flow", "ncc", "flow")}
    for kind in searches:
        tracker = PatchTracker(Frame(image), CENTRE, SIZE, kind)
        real = tracker._ncc

        def counted(frame: Frame, pose: Pose, kind: str = kind, real=real) -> tuple[Pose, float]:
            searches[kind] += 1
            return real(frame, pose)

        monkeypatch.setattr(tracker, "_ncc", counted)
        for k in range(1, 6):
            pose, score = tracker.update(Frame(moved(image, CENTRE, 0.0, 0.0, seed=k)),
                                         Pose(*CENTRE))
            assert score > 0.9 and abs(pose.u - CENTRE[0]) < 0.05
    assert searches == {"ncc+flow": 1, "ncc": 5, "flow": 0}


def test_a_reference_patch_is_the_object_s_own_pixels_centred_on_it() -> None:
    """The chain and OpenCV trackers score by a patch cut around the object's centre: at a
    whole-pixel centre it is the image's pixels around it, unresampled."""
    image = texture(80, 100, seed=3)
    reference = Reference.around(Frame(image), (50.0, 40.0), (21, 15))
    assert np.array_equal(reference.patch, image[33:48, 40:61])
    assert reference.centre == (10.0, 7.0)
    assert reference.score(Frame(image), Pose(50.0, 40.0)) > 0.999


def test_the_chain_tracker_adds_up_each_frame_s_rotation() -> None:
    """Two frames each turned 0.02 rad (and moved 1 px, 0.5 px) from the last: the chain's
    angle is their sum."""
    image = texture(300, 400, seed=9)
    tracker = make_tracker("chain", Frame(image), CENTRE, SIZE)
    pose, _ = tracker.update(Frame(moved(image, CENTRE, 1.0, 0.5, 0.02)), Pose(*CENTRE))
    assert abs(pose.theta - 0.02) < 2e-3
    pose, score = tracker.update(Frame(moved(image, CENTRE, 2.0, 1.0, 0.04, seed=4)), pose)
    assert abs(pose.theta - 0.04) < 2e-3 and score > 0.9
    assert abs(pose.u - CENTRE[0] - 2.0) < 0.1 and abs(pose.v - CENTRE[1] - 1.0) < 0.1


def test_an_unknown_tracker_is_named_with_the_known_ones():
    """Called from Python, where no argparse choice list stands before it."""
    for kind in ("ncc+flow", "ncc", "flow", "chain", "mil"):
        check_tracker(kind)
    with pytest.raises(ValueError, match=r"^unknown tracker 'kcf'; known: ncc\+flow, ncc, "
                                         r"flow, chain, mil$"):
        check_tracker("kcf")

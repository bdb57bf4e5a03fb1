"""Patch tracking against the first frame: sub-pixel translation and rotation without drift."""

import numpy as np
import pytest

from calibration.vision.flow import RigidFlow, warp_to_reference
from calibration.vision.tracking import (
    LOST_SCORE,
    Frame,
    MultiTracker,
    PatchTracker,
    Pose,
    Tracker,
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


def test_rigid_flow_sign_conventions() -> None:
    image = texture(300, 400)
    ref_centre = (55.0, 65.0)
    ref = warp_to_reference(image, CENTRE, 0.0, ref_centre, SIZE)
    flow = RigidFlow(ref, ref_centre)
    cur = warp_to_reference(moved(image, CENTRE, 0.4, 0.2, 0.01, noise=0.0), CENTRE, 0.0,
                            ref_centre, SIZE)
    m = flow.measure(cur)
    assert abs(m.du - 0.4) < 0.05 and abs(m.dv - 0.2) < 0.05 and abs(m.dtheta - 0.01) < 1e-3


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

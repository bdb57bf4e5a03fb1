"""Warnings on tracked paths: frames listed as ranges, trackers that may have swapped, and
frames in which a marked object was not followed."""

import numpy as np
import pytest

from calibration.trajectories import ObjectPath
from calibration.vision.checks import frame_ranges, gap_warnings, swap_warnings

FPS = 20.0


def path(frames: range | list[int], x_m: float | np.ndarray, z_m: float = 0.5) -> ObjectPath:
    """An object seen in `frames` (at FPS), its centre at x_m (one value or one a frame)."""
    t_s = np.asarray(frames, float) / FPS
    x = np.broadcast_to(np.asarray(x_m, float), t_s.shape).copy()
    return ObjectPath(t_s, x, np.full_like(t_s, z_m), np.zeros_like(t_s))


@pytest.mark.parametrize("frames,text", [([], ""), ([4], "4"), ([5, 6], "5-6"),
                                         ([1, 2, 3, 7], "1-3, 7"), ([0, 2, 4], "0, 2, 4"),
                                         ([3, 9, 10, 11, 20, 21], "3, 9-11, 20-21")])
def test_frames_are_listed_as_runs(frames: list[int], text: str) -> None:
    assert frame_ranges(frames) == text


def test_neighbours_that_stay_apart_give_no_warning() -> None:
    """Two bundles 0.28 m long side by side: centres 0.28 m apart, more than a half-box."""
    paths = {"L1C1R1": path(range(40), 0.0), "L1C2R1": path(range(40), 0.28)}
    assert swap_warnings(paths, {"L1C1R1": 0.14, "L1C2R1": 0.14}, FPS) == []


def test_a_tracker_that_jumps_onto_its_neighbour_is_named_with_the_frames_it_sat_there() -> None:
    """In frames 10-12 L1C1R1's tracker reads its neighbour's centre (2 cm off it), then
    returns: the pair is warned about once, with those frames."""
    x = np.zeros(40)
    x[10:13] = 0.26
    paths = {"L1C1R1": path(range(40), x), "L1C2R1": path(range(40), 0.28)}
    warnings = swap_warnings(paths, {"L1C1R1": 0.14, "L1C2R1": 0.14}, FPS)
    assert warnings == ["L1C1R1 and L1C2R1 overlap in frames 10-12: their identities may "
                        "have swapped"]


def test_the_smaller_half_box_decides_and_only_frames_both_were_seen_in_count() -> None:
    """A 0.10 m closeness is an overlap for two boxes with half-sides 0.14 and 0.12 m but not
    for one of 0.08 m; frames where one object was lost are not compared."""
    near = {"a": path(range(10), 0.0), "b": path(range(5, 15), 0.10)}
    assert swap_warnings(near, {"a": 0.14, "b": 0.12}, FPS) == [
        "a and b overlap in frames 5-9: their identities may have swapped"]
    assert swap_warnings(near, {"a": 0.14, "b": 0.08}, FPS) == []


def test_a_single_frame_seen_together_is_compared() -> None:
    """Two bundles whose paths meet in frame 9 only, where they overlap: that frame is named."""
    paths = {"a": path(range(10), 0.0), "b": path(range(9, 20), 0.05)}
    assert swap_warnings(paths, {"a": 0.14, "b": 0.14}, FPS) == [
        "a and b overlap in frames 9: their identities may have swapped"]


def test_objects_without_a_box_or_without_common_frames_are_not_compared() -> None:
    """The pallet (no half-box given) under a bundle, and two bundles never seen together."""
    paths = {"pallet": path(range(20), 0.0), "L1C1R1": path(range(20), 0.0),
             "L2C1R1": path(range(20, 40), 0.0)}
    assert swap_warnings(paths, {"L1C1R1": 0.14, "L2C1R1": 0.14}, FPS) == []


def test_an_object_followed_in_every_frame_gives_no_gap_warning() -> None:
    assert gap_warnings("L1C1R1", list(range(30)), 30) == []


def test_frames_missed_inside_a_path_are_interpolated_and_those_outside_it_left_out() -> None:
    """Seen from frame 3 to 27 but not in 10-12: its path spans 3-27 with 10-12 filled in
    between their neighbours; 0-2 and 28-29 it has none."""
    seen = [k for k in range(3, 28) if k not in (10, 11, 12)]
    assert gap_warnings("L2C3R1", seen, 30) == [
        "L2C3R1: no marker followed in 8 frames (frames 10-12 interpolated; frames 0-2, 28-29 "
        "left out)"]
    assert gap_warnings("pallet", list(range(5, 30)), 30) == [
        "pallet: no marker followed in 5 frames (frames 0-4 left out)"]
    assert gap_warnings("sled", [0, 1, 4, 5], 6) == [
        "sled: no marker followed in 2 frames (frames 2-3 interpolated)"]


@pytest.mark.parametrize("seen,frames,text", [
    ([0, 2, 3], 4, "frames 1 interpolated"),          # right after the first sighting
    ([0, 1, 3], 4, "frames 2 interpolated"),          # right before the last
    ([1, 2, 3], 5, "frames 0, 4 left out"),           # one frame each side, none between
])
def test_a_missed_frame_next_to_a_path_s_ends_is_placed_on_its_side_of_them(
        seen: list[int], frames: int, text: str) -> None:
    """Frames beside the first and last sighting: between them interpolated, beyond left out."""
    assert gap_warnings("L1C1R1", seen, frames) == [
        f"L1C1R1: no marker followed in {frames - len(seen)} frames ({text})"]

"""Template matching: every copy of the template found once, at sub-pixel centres."""

import numpy as np

from calibration.vision.detection import find_template, nms, subpixel_peak
from tests.calibration.vision.vision_frames import moved, texture


def test_finds_each_copy_once_with_subpixel_centre() -> None:
    face = texture(60, 80, seed=3)
    image = np.full((300, 500), 128, np.uint8)
    centres = [(100.0, 80.0), (190.0, 80.0), (100.0, 200.0), (350.0, 150.0)]
    for u, v in centres:
        image[int(v) - 30:int(v) + 30, int(u) - 40:int(u) + 40] = face
    shifted = moved(image, (0.0, 0.0), 0.3, -0.4, noise=1.0)
    found = find_template(shifted, face, threshold=0.6)
    assert len(found) == len(centres)
    for u, v in centres:
        # the pasted face spans [u-40, u+40): its centre is at u - 0.5, v - 0.5
        best = min(found, key=lambda d: abs(d.u - u) + abs(d.v - v))
        assert abs(best.u - (u - 0.5 + 0.3)) < 0.15
        assert abs(best.v - (v - 0.5 - 0.4)) < 0.15
        assert best.score > 0.9


def test_nothing_above_threshold_on_unrelated_texture() -> None:
    assert find_template(texture(200, 300, seed=1), texture(40, 40, seed=2), 0.6) == []


def test_nms_keeps_best_of_overlapping_boxes() -> None:
    centres = np.array([[10.0, 10.0], [12.0, 10.0], [60.0, 10.0]])
    keep = nms(centres, np.array([0.8, 0.9, 0.7]), (20, 20))
    assert keep.tolist() == [1, 2]


def _paraboloid(col: float, row: float, size: int = 5) -> np.ndarray:
    x = np.arange(float(size))
    return -((x[None, :] - col) ** 2) - ((x[:, None] - row) ** 2)


def test_subpixel_peak_of_a_parabola() -> None:
    dc, dr = subpixel_peak(_paraboloid(2.3, 1.8), 2, 2)
    assert abs(dc - 0.3) < 1e-9 and abs(dr + 0.2) < 1e-9


def test_a_template_as_large_as_the_image_is_found_once_and_a_larger_one_nowhere() -> None:
    """One placement only (a 20 x 30 template in a 20 x 30 image): one match, centred on the
    image's centre pixel (14.5, 9.5). An image a row or a column short has none."""
    face = texture(20, 30, seed=3)
    (found,) = find_template(face, face, threshold=0.6)
    assert (found.u, found.v, found.width, found.height) == (14.5, 9.5, 30, 20)
    assert found.score > 0.999
    assert find_template(face[:, :-1], face, 0.6) == []
    assert find_template(face[:-1], face, 0.6) == []


def test_nms_drops_a_box_overlapping_a_better_one_by_more_than_the_iou() -> None:
    """Two 20 x 20 boxes 10 px apart share 200 px^2 of 600: IoU 0.33 > 0.3, the worse dropped;
    11 px apart, 180 of 620: IoU 0.29, both kept."""
    scores = np.array([0.9, 0.8])
    assert nms(np.array([[10.0, 10.0], [20.0, 10.0]]), scores, (20, 20)).tolist() == [0]
    assert nms(np.array([[10.0, 10.0], [21.0, 10.0]]), scores, (20, 20)).tolist() == [0, 1]
    assert nms(np.array([[10.0, 10.0], [10.0, 21.0]]), scores, (20, 20)).tolist() == [0, 1]


def test_a_peak_next_to_the_map_s_edge_is_refined_and_one_on_it_is_not() -> None:
    """The parabola needs a neighbour on each side: at columns and rows 1 and 3 of a 5 x 5 map
    it has them; at 0 and 4 the offset is 0."""
    dc, dr = subpixel_peak(_paraboloid(1.3, 3.2), 3, 1)
    assert abs(dc - 0.3) < 1e-9 and abs(dr - 0.2) < 1e-9
    dc, dr = subpixel_peak(_paraboloid(3.2, 1.3), 1, 3)
    assert abs(dc - 0.2) < 1e-9 and abs(dr - 0.3) < 1e-9
    assert subpixel_peak(_paraboloid(0.2, 4.1), 4, 0) == (0.0, 0.0)


def test_a_flat_or_hollow_neighbourhood_gives_no_offset() -> None:
    """No parabola opening downwards (equal scores, or a saddle along one axis): offset 0."""
    assert subpixel_peak(np.ones((3, 3)), 1, 1) == (0.0, 0.0)
    hollow = np.array([[0.0, 0.5, 0.0], [0.9, 0.5, 0.2], [0.0, 0.5, 0.0]])
    assert subpixel_peak(hollow, 1, 1) == (0.0, 0.0)

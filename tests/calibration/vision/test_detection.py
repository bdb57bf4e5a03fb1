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


def test_subpixel_peak_of_a_parabola() -> None:
    x = np.arange(5.0)
    scores = -((x[None, :] - 2.3) ** 2) - ((x[:, None] - 1.8) ** 2)
    dc, dr = subpixel_peak(scores, 2, 2)
    assert abs(dc - 0.3) < 1e-9 and abs(dr + 0.2) < 1e-9

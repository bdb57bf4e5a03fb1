"""Synthetic recordings' textures (calibration/textures.py) have what the tracker needs of real
footage: one printed design every bundle of a load shares (one template finds them all), a film
of its own on each bundle (detail for optical flow), a pallet whose fork openings are in shadow,
and sled markers ArUco decodes on their own quiet zone. Everything drawn from a seed."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calibration import textures

PX_PER_M = 400.0
BUNDLE_FACE_M = (0.28, 0.33)


def grey(image: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)


def ncc(a: np.ndarray, b: np.ndarray) -> float:
    """Normalised cross-correlation of two images of one size, as the tracker's NCC scores."""
    return float(cv2.matchTemplate(grey(a), grey(b), cv2.TM_CCOEFF_NORMED).max())


def test_a_face_is_drawn_at_the_texture_s_pixels_per_metre_and_repeats_under_its_seed():
    design = textures.label_design(BUNDLE_FACE_M, PX_PER_M, seed=0)
    assert design.shape == (132, 112, 3) and design.dtype == np.uint8   # 0.33 x 0.28 m
    assert np.array_equal(design, textures.label_design(BUNDLE_FACE_M, PX_PER_M, seed=0))
    assert not np.array_equal(design, textures.label_design(BUNDLE_FACE_M, PX_PER_M, seed=1))


def test_every_bundle_of_a_load_shows_one_design_under_a_film_of_its_own():
    design = textures.label_design(BUNDLE_FACE_M, PX_PER_M, seed=0)
    first, second = (textures.bundle_texture(design, 0, i) for i in (0, 1))
    other_load = textures.bundle_texture(textures.label_design(BUNDLE_FACE_M, PX_PER_M, 1), 1, 0)
    assert ncc(first, second) > 0.9                   # one template finds both ...
    assert np.abs(first.astype(int) - second).mean() > 3   # ... yet each has its own detail
    assert ncc(first, other_load) < 0.7               # another product is another template
    assert np.array_equal(first, textures.bundle_texture(design, 0, 0))


def test_the_pallet_s_fork_openings_are_dark_between_light_blocks():
    pallet = textures.pallet_texture((1.2, 0.144), PX_PER_M, seed=0)
    board, block = round(0.022 * PX_PER_M), round(0.145 * PX_PER_M)
    inner = slice(board + 2, pallet.shape[0] - board - 2)
    opening = pallet[inner, block + 2:(pallet.shape[1] - block) // 2 - 2]
    assert opening.mean() < 60 < 120 < pallet[inner, 2:block - 2].mean()


@pytest.mark.parametrize("marker_id", [0, 7, 49])
def test_a_marker_decodes_on_its_own_quiet_zone(marker_id):
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    image = textures.marker_image(dictionary, marker_id, side_px=60)
    quiet = round(60 * textures.QUIET_ZONE)
    assert image.shape == (60 + 2 * quiet, 60 + 2 * quiet, 3)
    assert (image[:quiet] == 255).all() and (image[:, -quiet:] == 255).all()
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(grey(image).astype(
        np.uint8))
    assert ids is not None and ids.ravel().tolist() == [marker_id]
    far = quiet + 59                                  # the code's last pixel
    assert np.allclose(corners[0][0], [[quiet, quiet], [far, quiet], [far, far], [quiet, far]],
                       atol=0.5)

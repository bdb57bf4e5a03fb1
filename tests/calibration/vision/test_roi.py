"""Pixels and metres, pixel boxes, and the region of interest predicted from the sled profile,
each against numbers worked out by hand (binary fractions, so no rounding decides a pixel)."""

import numpy as np
import pytest

from calibration.vision.roi import Box, PixelMap, predict_roi, unit_extent_m
from wrapenv.load import BundlePlacement, Friction, Layout
from wrapenv.scene import SLED_DECK_M

#: 100 px a metre; the sled frame's origin at pixel (50, 400): u grows with x, v falls with z.
PIXMAP = PixelMap(100.0, 50.0, 400.0)


def test_the_camera_maps_x_along_u_and_z_up_the_image() -> None:
    assert PIXMAP.to_px(0.5, 0.25) == (100.0, 375.0)
    assert PIXMAP.to_px(-0.25, -0.5) == (25.0, 450.0)
    u, v = PIXMAP.to_px(np.array([1.5, -2.0]), np.array([0.75, 3.0]))
    assert np.array_equal(u, [200.0, -150.0]) and np.array_equal(v, [325.0, 100.0])
    assert PIXMAP.to_world(100.0, 375.0) == (0.5, 0.25)
    assert PIXMAP.to_world(*PIXMAP.to_px(1.25, 0.625)) == (1.25, 0.625)


def test_a_box_is_half_open_and_empty_without_width_or_height() -> None:
    box = Box(10, 20, 13, 24)
    assert (box.width, box.height) == (3, 4) and not box.empty
    assert not Box(10, 20, 11, 21).empty                # one pixel
    assert Box(10, 20, 10, 24).empty and Box(10, 20, 13, 20).empty
    assert Box(10, 20, 9, 24).empty and Box(10, 20, 13, 19).empty


def test_a_box_is_clipped_to_the_frame_grown_and_shifted_by_whole_pixels() -> None:
    assert Box(-5, -3, 700, 500).clip(640, 480) == Box(0, 0, 640, 480)
    assert Box(5, 3, 600, 400).clip(640, 480) == Box(5, 3, 600, 400)
    assert Box(10, 20, 13, 24).grow(2) == Box(8, 18, 15, 26)
    assert Box(10, 20, 13, 24).shift(2.6) == Box(13, 20, 16, 24)     # rounded, along u only
    assert Box(10, 20, 13, 24).shift(-2.4) == Box(8, 20, 11, 24)


def test_a_box_around_a_point_is_rounded_outwards() -> None:
    """A 4 x 6 rectangle centred on (10.5, 20): [8.5, 12.5] x [17, 23], each pixel it touches
    kept (the far edges' pixels too: half-open, +1)."""
    assert Box.around(10.5, 20.0, 4.0, 6.0) == Box(8, 17, 14, 24)


def _layout(*bundles: tuple[float, float]) -> Layout:
    """An EUR pallet (1.2 x 0.8 x 0.144 m) with 0.28 x 0.19 x 0.33 m bundles at (x, y)."""
    placed = tuple(BundlePlacement(f"L1C{i}R1", 1, (x, y, 0.309), (0.28, 0.19, 0.33), 9.3)
                   for i, (x, y) in enumerate(bundles, start=1))
    return Layout((1.2, 0.8, 0.144), 25.0, placed, Friction(), False)


def test_a_unit_s_extent_is_its_pallet_and_bundles_down_to_the_deck_s_face() -> None:
    """Bundles within the pallet: the pallet's ends; the top is the bundles' (0.144 + 0.33)."""
    x0, x1, z0, z1 = unit_extent_m(_layout((-0.2, 0.3), (0.2, -0.3)))
    assert (x0, x1, z0) == (-0.6, 0.6, -SLED_DECK_M)
    assert z1 == pytest.approx(0.474, abs=1e-12)


def test_an_overhanging_bundle_and_the_sled_s_markers_widen_the_extent() -> None:
    """A bundle centred 0.5 m behind and one 0.7 m ahead along x reach past the pallet by
    their half-length (0.14 m; their width along y does not count); markers 0.9 m ahead too."""
    layout = _layout((-0.5, 0.0), (0.7, 0.0))
    x0, x1, _, _ = unit_extent_m(layout)
    assert (x0, x1) == pytest.approx((-0.64, 0.84), abs=1e-12)
    assert unit_extent_m(layout, (0.9,))[1] == 0.9
    assert unit_extent_m(layout, (-1.0,))[0] == -1.0


def test_the_region_of_interest_follows_the_sled_with_its_margin_and_is_clipped() -> None:
    """The unit spans x -0.5..0.5, z -0.125..0.5; the sled at 1 m; a 0.25 m margin: u from
    50 + 100 x 0.25 = 75 to 50 + 100 x 1.75 = 225 (+1), v from 400 - 100 x 0.75 = 325 to
    400 + 100 x 0.375 = 437.5 (438, +1). With the sled at 5 m the frame's edge cuts it."""
    extent = (-0.5, 0.5, -0.125, 0.5)
    assert predict_roi(PIXMAP, extent, 1.0, (640, 480), 0.25) == Box(75, 325, 226, 439)
    assert predict_roi(PIXMAP, extent, 1.5, (640, 480), 0.25) == Box(125, 325, 276, 439)
    assert predict_roi(PIXMAP, extent, 1.0, (640, 480), 0.0) == Box(100, 350, 201, 414)
    assert predict_roi(PIXMAP, extent, 5.0, (600, 430), 0.25) == Box(475, 325, 600, 430)

"""The first frame's objects: the sled and the pallet placed from the layout, the front row's
bundles named after the nearest layout position and started at their best template match, each
box inset from its outline; pixels worked out by hand."""

import pytest

from calibration.vision.detection import Detection
from calibration.vision.objects import (
    MIN_BOX_PX,
    TrackedObject,
    View,
    box_size,
    bundles,
    sled_and_pallet,
)
from calibration.vision.roi import PixelMap
from wrapenv.load import BundlePlacement, Friction, Layout

#: 200 px a metre, the sled frame's origin at pixel (50, 400); the sled at x 0.25 m in frame 0.
PIXMAP = PixelMap(200.0, 50.0, 400.0)
SLED_X0_M = 0.25
BUNDLE_M = (0.28, 0.19, 0.33)


def _view(*bundle_xs: float) -> View:
    """An EUR pallet (1.2 x 0.8 x 0.144 m) with one layer of bundles facing the camera at
    `bundle_xs` (row R1) and one behind them (R2), which the camera does not see."""
    row = [BundlePlacement(f"L1C{i}R1", 1, (x, -0.3, 0.309), BUNDLE_M, 9.3)
           for i, x in enumerate(bundle_xs, start=1)]
    hidden = BundlePlacement("L1C1R2", 1, (0.0, 0.3, 0.309), BUNDLE_M, 9.3)
    layout = Layout((1.2, 0.8, 0.144), 25.0, (*row, hidden), Friction(), False)
    return View(layout, PIXMAP, (640, 480), SLED_X0_M)


def test_a_box_is_whole_pixels_and_never_smaller_than_the_least_that_can_be_followed() -> None:
    assert box_size(51.2, 61.6) == (51, 62)
    assert box_size(3.0, 40.0) == (MIN_BOX_PX, 40) and box_size(40.0, 0.4) == (40, MIN_BOX_PX)


def test_the_sled_starts_where_its_markers_put_it_and_the_pallet_where_the_profile_does() -> None:
    """The sled's deck face (0.1 m thick, centred 0.05 m below z 0) at the markers' 0.5 m, as
    long as the pallet and 0.1 m either side: 280 px by (0.1 - 2 x 0.012) x 200 = 15 px. The
    pallet at the profile's 0.25 m, half its 0.144 m up: (100, 385.6), its box inset 0.024 m:
    235 x 24 px."""
    sled, pallet = sled_and_pallet(_view(0.0), sled_x0_m=0.5)
    assert sled == TrackedObject("sled", (150.0, 410.0), (280, 15))
    assert pallet.name == "pallet" and pallet.size_px == (235, 24)
    assert pallet.centre_px == pytest.approx((100.0, 385.6), abs=1e-9)


def test_each_front_bundle_starts_at_its_best_match_near_its_layout_position() -> None:
    """L1C1R1 at x -0.2 m sits at (60, 338.2) px; of two matches within its radius
    (0.35 x 0.28 m x 200 = 19.6 px) the higher score's is taken. L1C2R1 at (160, 338.2) has
    one 25 px off, outside the radius: it starts from the layout, said once. The hidden row
    (R2) is not followed. Boxes: (0.28 - 0.024) x 200 = 51 by (0.33 - 0.024) x 200 = 61 px."""
    matches = [Detection(65.0, 340.0, 0.8, 56, 66), Detection(70.0, 338.0, 0.9, 56, 66),
               Detection(185.0, 338.2, 0.95, 56, 66)]
    warnings: list[str] = []
    found = {o.name: o for o in bundles(_view(-0.2, 0.3), matches, warnings)}
    assert sorted(found) == ["L1C1R1", "L1C2R1"]
    assert found["L1C1R1"].centre_px == (70.0, 338.0)
    assert found["L1C2R1"].centre_px == pytest.approx((160.0, 338.2), abs=1e-9)
    assert {o.size_px for o in found.values()} == {(51, 61)}
    assert warnings == ["L1C2R1: no template match near its layout position in frame 0; "
                        "started from the layout"]


def test_a_match_just_inside_the_radius_counts() -> None:
    """19 px from L1C2R1's position, within its 19.6 px: it is taken."""
    warnings: list[str] = []
    found = bundles(_view(0.3), [Detection(179.0, 338.2, 0.7, 56, 66)], warnings)
    assert [o.centre_px for o in found] == [(179.0, 338.2)] and warnings == []


def test_without_a_template_every_front_bundle_starts_from_the_layout_unwarned() -> None:
    warnings: list[str] = []
    found = bundles(_view(-0.2, 0.3), None, warnings)
    assert [o.name for o in found] == ["L1C1R1", "L1C2R1"]
    assert [o.centre_px for o in found] == [pytest.approx((60.0, 338.2), abs=1e-9),
                                            pytest.approx((160.0, 338.2), abs=1e-9)]
    assert warnings == []

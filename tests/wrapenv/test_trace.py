"""What a bench run records, read in the pallet's frame (wrapenv/trace.py): EUMOS 40509 measures
a load's displacement on its pallet, so a pallet that slides or turns on the sled carries its
bundles without displacing them. Hand-made traces; tests/wrapenv/test_eumos.py judges them.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from wrapenv.trace import Trace, in_pallet_frame

#: Two bundles on the pallet's deck, in the pallet's frame: one 0.3 m ahead of its centre, one
#: 0.2 m to its side and a layer up.
ON_PALLET_M = np.array([[0.3, 0.0, 0.25], [0.0, 0.2, 0.55]])


def yaw(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def carried(pallet_xy_m: list[tuple[float, float]], yaw_rad: list[float],
            slid_m: np.ndarray | None = None) -> Trace:
    """The pallet at `pallet_xy_m[t]` turned by `yaw_rad[t]` about the vertical; the bundles
    at `ON_PALLET_M` on it, plus `slid_m[t]` (in the pallet's frame) where given."""
    steps = len(yaw_rad)
    rot = np.array([yaw(a) for a in yaw_rad])
    pallet = np.array([[x, y, 0.072] for x, y in pallet_xy_m])
    on = np.broadcast_to(ON_PALLET_M, (steps, 2, 3)) + (0.0 if slid_m is None else slid_m)
    bundles = pallet[:, None, :] + np.einsum("tab,tnb->tna", rot, on)
    return Trace(level_g=0.5, load_height_m=0.8, names=("L1C1R1", "L2C1R1"),
                 bottom_z_m=np.array([0.1, 0.4]), t_s=np.arange(steps) * 0.1,
                 sled_accel_mps2=np.zeros(steps), pallet_pos_m=pallet, pallet_rot=rot,
                 bundle_pos_m=bundles, bundle_rot=np.broadcast_to(rot[:, None], (steps, 2, 3, 3)),
                 layers=np.array([1, 2]))


def test_bundles_carried_by_a_pallet_that_slides_and_turns_have_not_moved():
    t = carried([(0.0, 0.0), (-0.05, 0.01), (-0.12, 0.03)], [0.0, 0.05, math.radians(10)])
    assert np.allclose(t.bundle_displacement_m(), 0.0)
    assert np.allclose(t.permanent_total_m(), 0.0)
    assert t.layer_shift_m() == pytest.approx(0.0, abs=1e-12)
    assert np.allclose(t.dropped_m(), 0.0)
    # the pallet itself slid 0.124 m on the sled: that is the pallet's slip, not the load's
    assert t.pallet_slip_m() == pytest.approx(math.hypot(0.12, 0.03))


def test_a_bundle_that_slides_on_a_turned_pallet_is_measured_along_the_pallet():
    # the pallet turned 30° and stayed there; the top bundle slid 4 cm back along the
    # pallet's own x axis, which in the sled's frame is (-4 cos 30°, -4 sin 30°) cm
    slid = np.zeros((2, 2, 3))
    slid[1, 1, 0] = -0.04
    t = carried([(0.0, 0.0), (0.0, 0.0)], [math.radians(30)] * 2, slid)
    assert t.permanent_total_m() == pytest.approx([0.0, 0.04])
    moved = t.bundle_pos_m[1, 1] - t.bundle_pos_m[0, 1]
    assert moved[:2] == pytest.approx([-0.04 * math.cos(math.radians(30)),
                                       -0.04 * math.sin(math.radians(30))])
    # the top layer's mean moved 4 cm on the layer below, which stayed on the pallet
    assert t.layer_shift_m() == pytest.approx(0.04)


def test_the_elastic_path_is_the_horizontal_distance_from_the_first_sample():
    slid = np.zeros((3, 2, 3))
    slid[1, 0] = (-0.03, 0.04, 0.0)     # 5 cm out (3-4-5) ...
    slid[2, 0] = (-0.003, 0.0, -0.01)   # ... 3 mm back for good, and 1 cm lower
    t = carried([(0.0, 0.0), (0.02, 0.0), (0.02, 0.0)], [0.0, 0.2, 0.2], slid)
    assert t.bundle_displacement_m()[:, 0] == pytest.approx([0.0, 0.05, 0.003])
    assert t.permanent_total_m()[0] == pytest.approx(0.003)
    assert t.dropped_m() == pytest.approx([0.01, 0.0])


def test_a_later_level_is_measured_from_where_the_unit_was_first_put_on_the_sled():
    origin = ON_PALLET_M + [[0.02, 0.0, 0.0], [0.0, 0.0, 0.0]]  # bundle 1 stood 2 cm ahead
    t = carried([(0.0, 0.0), (0.0, 0.0)], [0.0, 0.0])
    later = Trace(**{**t.__dict__, "origin_m": origin})
    assert later.moved_before_m() == pytest.approx(0.02)
    assert later.permanent_total_m() == pytest.approx([0.02, 0.0])
    assert t.moved_before_m() == 0.0                         # a first level


def test_the_final_tilt_is_the_angle_of_a_bundle_s_vertical_axis_to_the_world_s():
    t = carried([(0.0, 0.0)] * 2, [0.0, 0.0])
    c, s = math.cos(0.3), math.sin(0.3)
    tipped = t.bundle_rot.copy()
    tipped[-1, 0] = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    assert Trace(**{**t.__dict__, "bundle_rot": tipped}).tilt_rad() == pytest.approx([0.3, 0.0])
    # turning on the deck (yaw) is no tilt
    assert carried([(0.0, 0.0)] * 2, [0.0, 1.0]).tilt_rad() == pytest.approx([0.0, 0.0])


def test_one_sample_and_a_whole_trace_go_into_the_pallet_s_frame_alike():
    t = carried([(0.0, 0.0), (0.1, -0.2)], [0.0, 0.7])
    whole = in_pallet_frame(t.pallet_pos_m, t.pallet_rot, t.bundle_pos_m)
    for k in range(2):
        one = in_pallet_frame(t.pallet_pos_m[k], t.pallet_rot[k], t.bundle_pos_m[k])
        assert one == pytest.approx(whole[k])
        assert one == pytest.approx(ON_PALLET_M)


def test_each_layer_s_shift_is_taken_on_the_layer_below_it():
    # three layers of one bundle each: the first slid 1 cm on the pallet, the second 3 cm (2 on
    # the first), the third 3.5 cm (0.5 on the second): the largest shift is the second's 2 cm
    t = carried([(0.0, 0.0), (0.0, 0.0)], [0.0, 0.0])
    bundles = np.zeros((2, 3, 3))
    bundles[:, :, 2] = [0.25, 0.55, 0.85]
    bundles[1, :, 0] = [-0.01, -0.03, -0.035]
    upright = np.broadcast_to(np.eye(3), (2, 3, 3, 3))
    three = Trace(**{**t.__dict__, "names": ("L1", "L2", "L3"), "bottom_z_m": np.zeros(3),
                     "bundle_pos_m": bundles, "bundle_rot": upright,
                     "layers": np.array([1, 2, 3])})
    assert three.layer_shift_m() == pytest.approx(0.02)
    # read as one layer, the three bundles' mean moved 2.5 cm on the pallet
    assert Trace(**{**three.__dict__, "layers": None}).layer_shift_m() == pytest.approx(0.025)


def test_the_pallet_s_slip_is_from_where_it_stood_when_the_level_began():
    t = carried([(0.5, -0.2), (0.47, -0.16)], [0.0, 0.0])
    assert t.pallet_slip_m() == pytest.approx(0.05)


def test_what_a_later_level_carries_in_is_horizontal_and_from_its_first_sample():
    # bundle 1 stood 3 cm ahead and 1 cm lower when this level began, then slid 4 cm more
    origin = ON_PALLET_M + [[-0.03, 0.0, 0.01], [0.0, 0.0, 0.0]]
    slid = np.zeros((2, 2, 3))
    slid[1, 0, 0] = 0.04
    t = carried([(0.0, 0.0), (0.0, 0.0)], [0.0, 0.0], slid)
    later = Trace(**{**t.__dict__, "origin_m": origin})
    assert later.moved_before_m() == pytest.approx(0.03)
    assert later.permanent_total_m() == pytest.approx([0.07, 0.0])


def test_a_rotation_rounded_a_hair_past_upright_is_no_tilt():
    t = carried([(0.0, 0.0)] * 2, [0.0, 0.0])
    rounded = t.bundle_rot.copy()
    rounded[-1, 0, 2, 2] = 1.0 + 4e-16      # what a product of rotations can round to
    rounded[-1, 1, 2, 2] = -1.0 - 4e-16     # upside down
    assert Trace(**{**t.__dict__, "bundle_rot": rounded}).tilt_rad() == pytest.approx(
        [0.0, math.pi])

"""Rest under a steady load (wrapenv/rest.py), without Bullet: when a unit counts as resting,
the acceleration below which nothing can start to move on its own, and which steps a run may
record without simulating them. tests/wrapenv/test_bench_skip.py checks the same rules on the
bench, against runs taken step by step to the end.

Poses are given as the bench's state arrays: row 0 the pallet, then one row per bundle.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from wrapenv.load import Layout, LoadUnit
from wrapenv.profile import G
from wrapenv.rest import FLAT_RAD, Rest, quiet_accel_mps2

DRIFT_M = 0.001


def unit(size=(0.28, 0.19, 0.33), static=(0.45, 0.5, 0.3), layers=1) -> Layout:
    """One bundle (a column of `layers`) on an EUR pallet (0.144 m high, 0.8 m wide); `static`
    the sled–pallet, pallet–bundle and bundle–bundle static coefficients."""
    sp, pb, bb = static
    return LoadUnit.from_dict({
        "pallet": {"preset": "EUR"},
        "bundle": dict(zip(("length_m", "width_m", "height_m"), size, strict=True),
                       mass_kg=9.3),
        "stack": {"layers": layers, "pattern": "explicit", "positions": [[0.0, 0.0]]},
        "friction": {"sled_pallet": {"static": sp, "kinetic": sp},
                     "pallet_bundle": {"static": pb, "kinetic": pb},
                     "bundle_bundle": {"static": bb, "kinetic": bb}},
    }).layout()


def poses(tilt_rad: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The pallet and one bundle, the bundle turned by `tilt_rad` about the y axis."""
    c, s = math.cos(tilt_rad), math.sin(tilt_rad)
    turned = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return np.array([[0.0, 0.0, 0.072], [0.0, 0.0, 0.309]]), np.stack([np.eye(3), turned])


#: A level's sled acceleration in three steady stretches: changes at steps 10 and 30.
ACCEL = np.r_[np.full(10, -2.0), np.full(20, -1.0), np.zeros(10)]


# -- the quiet acceleration ------------------------------------------------------------------

def test_a_lone_bundle_on_a_gripping_pallet_is_quiet_below_its_lowest_static_friction():
    # sliding: sled–pallet 0.45 < pallet–bundle 0.5; tipping 0.19 / 0.33 = 0.58 comes later
    assert quiet_accel_mps2(unit()) == pytest.approx(G * 0.45)
    assert quiet_accel_mps2(unit(static=(1.0, 0.5, 0.3))) == pytest.approx(G * 0.5)


def test_bundle_on_bundle_friction_counts_only_where_a_bundle_stands_on_another():
    assert quiet_accel_mps2(unit(static=(1.0, 1.0, 0.05))) == pytest.approx(G * 0.19 / 0.33)


def test_a_bundle_standing_on_another_is_quiet_below_their_static_friction():
    """Two layers of one bundle: bundle–bundle 0.2 decides, below the column's tipping
    (0.19 / 0.66 = 0.29) and the pallet's friction."""
    two = unit(static=(0.45, 0.5, 0.2), layers=2)
    assert quiet_accel_mps2(two) == pytest.approx(G * 0.2)


def test_a_load_as_wide_as_its_pallet_tips_with_the_pallet():
    # one 1.2 x 0.8 x 0.9 m bundle: the load tips about the pallet's edge at 0.8 / (0.144 + 0.9),
    # before the bundle would about its own (0.8 / 0.9)
    layout = unit(size=(1.2, 0.8, 0.9), static=(1.0, 1.0, 1.0))
    assert quiet_accel_mps2(layout) == pytest.approx(G * 0.8 / 1.044)


# -- rest: since when the bodies stayed where they were, under the same load -----------------

def test_a_rest_goes_on_while_no_body_leaves_its_place_by_more_than_the_drift():
    rest = Rest(unit(), ACCEL, DRIFT_M)
    pos, rot = poses()
    assert rest.observe(0, pos, rot) == 0
    jitter = pos + 0.9 * DRIFT_M
    assert rest.observe(5, jitter, rot) == 0          # a squeezed stack shakes on the spot
    moved = pos.copy()
    moved[1, 0] -= 1.5 * DRIFT_M
    assert rest.observe(6, moved, rot) == 6           # a new rest, from where it went
    assert rest.observe(7, moved, rot) == 6


def test_a_turn_of_ten_times_the_drift_in_radians_ends_a_rest():
    rest = Rest(unit(), ACCEL, DRIFT_M)
    pos, rot = poses()
    rest.observe(0, pos, rot)
    assert rest.observe(3, *poses(tilt_rad=9 * DRIFT_M)) == 0
    assert rest.observe(4, *poses(tilt_rad=11 * DRIFT_M)) == 4


def test_a_change_of_acceleration_starts_a_new_rest_even_where_nothing_moved():
    rest = Rest(unit(), ACCEL, DRIFT_M)
    pos, rot = poses()
    rest.observe(8, pos, rot)
    assert rest.observe(9, pos, rot) == 8
    assert rest.observe(10, pos, rot) == 10
    assert rest.observe(29, pos, rot) == 10
    assert rest.observe(30, pos, rot) == 30


def test_the_end_of_a_push_is_a_change_of_load():
    rest = Rest(unit(), ACCEL, DRIFT_M, push_until=20)
    pos, rot = poses()
    rest.observe(12, pos, rot)
    assert rest.observe(20, pos, rot) == 20


# -- which steps cannot change anything -----------------------------------------------------

def test_a_quiet_flat_unit_at_rest_is_unchanged_until_the_step_before_the_next_change():
    rest = Rest(unit(), ACCEL, DRIFT_M)               # quiet below 0.45 g = 4.4 m/s²
    _, rot = poses()
    assert rest.unchanged_until(0, rot, end=40) == 9      # from the level's first step
    assert rest.unchanged_until(3, rot, end=40) == 9
    assert rest.unchanged_until(12, rot, end=40) == 29
    assert rest.unchanged_until(12, rot, end=20) == 20  # never past the end asked for


def test_nothing_is_skipped_under_an_acceleration_that_could_move_a_body():
    rest = Rest(unit(), np.full(20, -0.46 * G), DRIFT_M)
    _, rot = poses()
    assert rest.unchanged_until(3, rot, end=20) == 3
    # exactly at the lowest static friction, friction holds with nothing to spare: not quiet
    at_limit = Rest(unit(), np.full(20, -quiet_accel_mps2(unit())), DRIFT_M)
    assert at_limit.unchanged_until(3, rot, end=20) == 3
    assert not at_limit.quiet_between(0, 20)


def test_nothing_is_skipped_while_a_bundle_leans_on_something():
    rest = Rest(unit(), ACCEL, DRIFT_M)
    assert rest.unchanged_until(3, poses(0.5 * FLAT_RAD)[1], end=40) == 9
    assert rest.unchanged_until(3, poses(1.5 * FLAT_RAD)[1], end=40) == 3


def test_a_bundle_lying_on_its_side_stands_as_firmly_as_upright():
    rest = Rest(unit(), ACCEL, DRIFT_M)
    assert rest.unchanged_until(3, poses(math.pi / 2)[1], end=40) == 9


def test_nothing_is_skipped_while_a_push_acts():
    rest = Rest(unit(), ACCEL, DRIFT_M, push_until=20)
    _, rot = poses()
    assert rest.unchanged_until(12, rot, end=40) == 12
    assert rest.unchanged_until(19, rot, end=40) == 19
    assert rest.unchanged_until(20, rot, end=40) == 29       # the push acts before step 20


def test_a_stretch_is_quiet_only_if_every_acceleration_in_it_is():
    accel = np.r_[np.full(10, -2.0), np.full(5, -0.5 * G), np.full(5, -2.0)]
    rest = Rest(unit(), accel, DRIFT_M)
    assert rest.quiet_between(0, 10)
    assert not rest.quiet_between(5, 12)
    assert rest.quiet_between(15, 20)
    assert rest.quiet_between(7, 7)                   # nothing left is quiet

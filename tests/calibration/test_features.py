"""What of a tracked test the fit compares: slips across contacts, turns, and the frames the
bench can predict (a body's path ends where it leaves its support, tips over or falls)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from calibration import features
from wrapenv.load import LoadUnit

#: 2 columnar layers of 2 x 2 bundles (0.28 x 0.19 x 0.33 m) on a 0.6 x 0.4 x 0.12 m pallet.
LOAD = {
    "name": "feature test unit",
    "pallet": {"length_m": 0.6, "width_m": 0.4, "height_m": 0.12, "mass_kg": 10.0},
    "bundle": {"length_m": 0.28, "width_m": 0.19, "height_m": 0.33, "mass_kg": 9.3},
    "stack": {"layers": 2, "pattern": "columnar"},
}
SEEN = {"pallet", "L1C1R1", "L1C2R1", "L2C1R1", "L2C2R1"}
T = np.arange(0.0, 3.0, 0.05)            # 20 fps, 3 s
H, L = 0.33, 0.28


@pytest.fixture(scope="module")
def body_map():
    return features.bodies(LoadUnit.from_dict(LOAD).layout(), SEEN)


def _still() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {name: (T, np.zeros((len(T), 3))) for name in SEEN}


def test_bodies_rest_on_what_is_seen_below_them(body_map):
    assert body_map["pallet"].supports == ()
    assert body_map["L1C1R1"].supports == (("pallet", 0.12),)
    assert body_map["L2C2R1"].supports == (("L1C2R1", H),)
    assert body_map["L2C1R1"].tip_rad == pytest.approx(math.atan2(L, H))
    # each slip isolates one contact pair
    assert [body_map[n].pair for n in ("pallet", "L1C1R1", "L2C2R1")] == [
        "sled_pallet", "pallet_bundle", "bundle_bundle"]
    # an upper bundle whose support is hidden (row 2 is not seen) is not compared
    hidden = features.bodies(LoadUnit.from_dict(LOAD).layout(), SEEN | {"L2C1R2"})
    assert "L2C1R2" not in hidden


def test_a_slip_is_the_motion_across_the_contact_only(body_map):
    """The lower layer slides 30 mm with the pallet still; the upper bundle rides along: the
    lower bundle slips 30 mm on the pallet, the upper one not at all on it."""
    states = _still()
    ride = np.linspace(0.0, -0.03, len(T))
    for name in ("L1C1R1", "L2C1R1"):
        states[name][1][:, 0] = ride
    slip = features.slips(states, body_map)
    assert slip["L1C1R1"][-1] == pytest.approx(-0.03)
    assert np.max(np.abs(slip["L2C1R1"])) < 1e-12
    assert np.max(np.abs(slip["pallet"])) == 0.0


def test_on_the_pallet_a_bundle_moved_its_own_slip_plus_its_supports(body_map):
    """The lower bundle slides 30 mm on the pallet and the upper one 50 mm more on it: the
    upper one moved 80 mm on the pallet, whichever interface slid; the pallet itself sliding on
    the sled (5 mm) moves nothing on the pallet. A replay whose upper bundle slides 1 m counts
    L / 2 for its own slip, as the fit's features do."""
    states = _still()
    lower, upper = np.linspace(0.0, -0.03, len(T)), np.linspace(0.0, -0.08, len(T))
    states["pallet"][1][:, 0] = np.linspace(0.0, -0.005, len(T))
    for name in SEEN - {"pallet"}:            # every bundle rides on the pallet ...
        states[name][1][:, 0] = states["pallet"][1][:, 0]
    states["L1C1R1"][1][:, 0] = states["pallet"][1][:, 0] + lower   # ... but the first column
    states["L2C1R1"][1][:, 0] = states["pallet"][1][:, 0] + upper
    moved = features.on_pallet(states, body_map)
    assert "pallet" not in moved
    assert moved["L1C1R1"][-1] == pytest.approx(-0.03)
    assert moved["L2C1R1"][-1] == pytest.approx(-0.08)
    assert np.max(np.abs(moved["L2C2R1"])) < 1e-12
    states["L2C1R1"][1][:, 0] = states["L1C1R1"][1][:, 0] - np.linspace(0.0, 1.0, len(T))
    assert features.on_pallet(states, body_map)["L2C1R1"][-1] == pytest.approx(-0.03 - L / 2)


def test_a_body_tipping_about_its_edge_does_not_slip_but_turns(body_map):
    """A top bundle rotating by a about its rear bottom edge: its centre moves by
    (L/2)(cos a - 1) - (H/2) sin a, its bottom centre by (L/2)(cos a - 1) only (second order),
    and its turn feature is (H/2) a."""
    states = _still()
    a = np.linspace(0.0, 0.3, len(T))
    xza = states["L2C1R1"][1]
    xza[:, 0] = L / 2 * (np.cos(a) - 1) - H / 2 * np.sin(a)
    xza[:, 2] = a
    slip = features.slips(states, body_map)["L2C1R1"]
    assert np.allclose(slip, L / 2 * (np.cos(a) - 1), atol=1e-12)
    frames = features.windows(states, body_map, sled_stop_s=10.0)
    vec = features.vector(states, body_map, frames)
    # blocks in name order: L1C1R1, L1C2R1, L2C1R1 (slip, then turn), ...
    k = frames["L2C1R1"]
    start = 2 * (frames["L1C1R1"] + frames["L1C2R1"])
    assert np.allclose(vec[start + k:start + 2 * k], H / 2 * a[:k])


def test_a_bundle_has_room_to_slip_until_its_centre_passes_its_supports_edge(body_map):
    """On the pallet (0.6 m long, the columns at x = -0.141 and +0.141 m, 2 mm apart): the back
    column's centre is 0.159 m from the pallet's back edge and 0.441 m from its front one; a
    bundle on a bundle of its size has half its length either way; the pallet half its own on
    the sled."""
    assert body_map["L1C1R1"].room_m == pytest.approx((0.159, 0.441))
    assert body_map["L1C2R1"].room_m == pytest.approx((0.441, 0.159))
    assert body_map["L2C1R1"].room_m == pytest.approx((L / 2, L / 2))
    assert body_map["pallet"].room_m == pytest.approx((0.3, 0.3))


def test_an_inner_bundle_sliding_farther_than_half_its_length_stays_predictable(body_map):
    """The bottom layer slides 0.2 m back on the pallet: the back column's centre passes the
    pallet's edge (0.159 m) and its window ends there; the front column's is still 0.24 m on
    the pallet, so its whole slide is compared, unclipped."""
    states = _still()
    slide = np.linspace(0.0, -0.2, len(T))
    for name in ("L1C1R1", "L1C2R1", "L2C1R1", "L2C2R1"):
        states[name][1][:, 0] = slide
    frames = features.windows(states, body_map, sled_stop_s=10.0)
    assert frames["L1C1R1"] == frames["L2C1R1"] == int(np.argmax(slide < -0.159))
    assert frames["L1C2R1"] == frames["L2C2R1"] == len(T)
    vec = features.vector(states, body_map, frames)
    start = 2 * frames["L1C1R1"]                      # L1C2R1's block follows L1C1R1's
    assert vec[start + len(T) - 1] == pytest.approx(-0.2)


def test_a_replay_counts_up_to_half_a_length_beyond_what_the_recording_showed(body_map):
    """Recorded: the front bottom bundle slid 0.1 m back on the pallet, the back one stayed.
    A replay in which both slide 0.35 m has come to another outcome: the front bundle counts
    0.1 + L / 2 = 0.24 m (its room is 0.441 m), the still one L / 2, as a still body always
    did; an upper bundle keeps L / 2, its room."""
    recorded = _still()
    recorded["L1C2R1"][1][:, 0] = np.linspace(0.0, -0.1, len(T))
    frames = features.windows(recorded, body_map, sled_stop_s=10.0)
    judged = features.reach(recorded, body_map, frames)
    assert judged["L1C2R1"].reach_m == pytest.approx((0.1 + L / 2, L / 2))
    assert judged["L1C1R1"].reach_m == pytest.approx((L / 2, L / 2))
    assert judged["L2C1R1"].reach_m == pytest.approx((L / 2, L / 2))
    replayed = _still()
    for name in ("L1C1R1", "L1C2R1"):
        replayed[name][1][:, 0] = np.linspace(0.0, -0.35, len(T))
    slips = features.slips(replayed, judged)
    assert judged["L1C2R1"].clipped(slips["L1C2R1"])[-1] == pytest.approx(-0.1 - L / 2)
    assert judged["L1C1R1"].clipped(slips["L1C1R1"])[-1] == pytest.approx(-L / 2)


def test_windows_end_where_a_body_leaves_its_support_and_carry_up(body_map):
    """L1C1R1 slides past the pallet's back edge at frame 30: its window and that of the
    bundle on it end there; the other column keeps every frame until 0.25 s after the sled
    stopped."""
    states = _still()
    slide = np.where(np.arange(len(T)) < 30, -0.004 * np.arange(len(T)), -0.2)
    states["L1C1R1"][1][:, 0] = slide
    frames = features.windows(states, body_map, sled_stop_s=2.0)
    first_lost = int(np.argmax(slide < -body_map["L1C1R1"].room_m[0]))
    assert frames["L1C1R1"] == frames["L2C1R1"] == first_lost
    assert frames["L1C2R1"] == frames["pallet"] == int(np.sum(T <= 2.0 + features.AFTER_STOP_S))


@pytest.mark.parametrize("column, value, limit", [
    (2, 0.8, "tip"),               # turned past atan(L / H) = 0.70 rad
    (1, -0.03, "fall"),            # dropped more than FALL_M
])
def test_windows_end_where_a_body_tips_over_or_falls(body_map, column, value, limit):
    """Counted from where the body was first tracked (here 0.1 m lower or 0.1 rad turned the
    other way than the layout's)."""
    states = _still()
    path = -0.1 + np.where(T < 1.0, 0.0, value)
    states["L2C2R1"][1][:, column] = path
    frames = features.windows(states, body_map, sled_stop_s=5.0)
    assert frames["L2C2R1"] == int(np.sum(T < 1.0))
    assert frames["L1C2R1"] == len(T)


def test_replayed_slips_past_the_edge_are_clipped(body_map):
    """A replay in which a bundle slides 1 m counts as 'past the edge' (L / 2), not metres."""
    states = _still()
    states["L2C2R1"][1][:, 0] = np.linspace(0.0, -1.0, len(T))
    frames = {name: len(T) for name in body_map}
    vec = features.vector(states, body_map, frames)
    assert vec.min() == pytest.approx(-L / 2)
    assert len(vec) == 2 * len(T) * len(body_map)


def test_a_column_that_tips_over_on_its_support_toppled(body_map):
    """A bundle turning past atan(l / h) about its front bottom edge, still on the pallet, is a
    toppled column; one that slides off the pallet's edge first and then tumbles is not."""
    assert not features.toppled(_still(), body_map)
    angle = np.linspace(0.0, 0.9, len(T))             # past atan(0.28 / 0.33) = 0.70 rad
    states = _still()
    x = L / 2 * (1 - np.cos(angle)) + H / 2 * np.sin(angle)   # its bottom edge stays put
    states["L1C1R1"][1][:] = np.stack([x, L / 2 * np.sin(angle) + H / 2 * (np.cos(angle) - 1),
                                       -angle], axis=1)
    assert features.toppled(states, body_map)
    states = _still()
    slide = np.minimum(np.linspace(0.0, 0.4, len(T)), 0.4)      # past half its length first
    tumble = np.where(slide > L / 2 + 0.05, 1.0, 0.0)
    states["L1C1R1"][1][:] = np.stack([-slide, -0.2 * tumble, -tumble], axis=1)
    assert not features.toppled(states, body_map)


def test_slips_and_turns_count_from_the_first_frame_tracked(body_map):
    """A bundle already 12 mm back, another turned 0.05 rad, when the recording starts: what
    each does is counted from there, not from where the layout put it."""
    states = _still()
    states["L2C2R1"][1][:, 0] = np.linspace(-0.012, -0.032, len(T))
    states["L2C1R1"][1][:, 2] = np.linspace(0.05, 0.15, len(T))
    frames = {name: len(T) for name in body_map}
    assert features.slips(states, body_map)["L2C2R1"][[0, -1]] == pytest.approx([0.0, -0.02])
    turn = features.vector(states, body_map, frames)[features.spans(frames)["L2C1R1"]][len(T):]
    assert turn[[0, -1]] == pytest.approx([0.0, H / 2 * 0.1])


def test_each_body_s_features_are_its_slip_then_its_turn_in_name_order():
    frames = {"pallet": 3, "L1C1R1": 2}
    assert {k: v.tolist() for k, v in features.spans(frames).items()} == {
        "L1C1R1": [0, 1, 2, 3], "pallet": [4, 5, 6, 7, 8, 9]}


def test_a_pallet_that_leaves_the_view_ends_every_window_above_it(body_map):
    """Windows carry up from the supports, the pallet's first: a pallet sliding off the sled's
    deck (dropping 5 cm at 1 s) ends every bundle's window there."""
    states = _still()
    states["pallet"][1][:, 1] = np.where(T < 1.0, 0.0, -0.05)
    frames = features.windows(states, body_map, sled_stop_s=5.0)
    assert set(frames.values()) == {int(np.sum(T < 1.0))}

"""Per-pair static and kinetic friction on Bullet's one multiplied coefficient per body
(wrapenv/friction.py): the solve for body coefficients, and the contact states that pick
static or kinetic values with hysteresis."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wrapenv.friction import SLIP_SPEED_MPS, STICK_SPEED_MPS, StickSlip, _side_contacts
from wrapenv.load import Friction, FrictionPair, LoadUnit
from wrapenv.scene import BenchScene

FRICTION = Friction(sled_pallet=FrictionPair(0.45, 0.34), pallet_bundle=FrictionPair(0.5, 0.4),
                    bundle_bundle=FrictionPair(0.3, 0.2))


def unit(layers: int) -> LoadUnit:
    return LoadUnit.from_dict({
        "name": "u", "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": layers, "pattern": "columnar"},
    }).with_friction(FRICTION)


def products(ss: StickSlip) -> dict[tuple[int, int], float]:
    """The coefficient Bullet uses at every resting contact: the product of its two bodies'."""
    mu = ss.coefficients()
    return {(c.body, c.other): float(mu[c.body] * mu[c.other]) for c in ss.resting}


def at_rest(n_bodies: int) -> tuple[np.ndarray, ...]:
    return (np.zeros((n_bodies, 3)), np.repeat(np.eye(3)[None], n_bodies, axis=0),
            np.zeros((n_bodies, 3)), np.zeros((n_bodies, 3)))


@pytest.mark.parametrize("layers", [1, 2, 3])
def test_a_columnar_stack_gets_every_pair_s_static_value_exactly(layers):
    """Resting contacts of a columnar stack form a tree (sled - pallet - one column per bundle
    chain), so body coefficients exist whose products are the wanted pair values."""
    ss = StickSlip(unit(layers).layout())
    for (body, other), mu in products(ss).items():
        want = (FRICTION.sled_pallet if (body, other) == (1, 0) else
                FRICTION.pallet_bundle if other == 1 else FRICTION.bundle_bundle).static
        assert mu == pytest.approx(want, rel=1e-9), (body, other)


def test_a_sliding_contact_takes_its_kinetic_value_and_the_others_keep_theirs():
    layout = unit(2).layout()
    ss = StickSlip(layout)
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    top = 2 + next(k for k, b in enumerate(layout.bundles) if b.layer == 2)
    vel[top, 0] = 2 * SLIP_SPEED_MPS  # one top bundle slides on the one below it
    changed = ss.update(pos, rot, vel, omega)
    assert top in changed
    got = products(ss)
    below = next(c.other for c in ss.resting if c.body == top)
    assert got[(top, below)] == pytest.approx(FRICTION.bundle_bundle.kinetic, rel=1e-9)
    assert got[(1, 0)] == pytest.approx(FRICTION.sled_pallet.static, rel=1e-9)
    assert ss.sliding_bodies() == {top, below}


def test_stopping_every_body_names_only_the_contacts_that_were_sliding():
    """A later level starts still: the contacts that slid are the ones to rebuild, and the
    pallet's grip on the sled, which did not change, is left alone."""
    layout = unit(2).layout()
    ss = StickSlip(layout)
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    top = 2 + next(k for k, b in enumerate(layout.bundles) if b.layer == 2)
    vel[top, 0] = 2 * SLIP_SPEED_MPS
    ss.update(pos, rot, vel, omega)
    below = next(c.other for c in ss.resting if c.body == top)
    assert ss.stick_all() == sorted([below, top])
    assert not ss.sliding.any() and ss.stick_all() == []
    assert products(ss) == products(StickSlip(layout))


def test_hysteresis_keeps_a_slide_going_until_it_is_slower_than_the_stick_speed():
    ss = StickSlip(unit(1).layout())
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    vel[2, 0] = 1.5 * SLIP_SPEED_MPS
    ss.update(pos, rot, vel, omega)
    assert ss.sliding.any()
    vel[2, 0] = (SLIP_SPEED_MPS + STICK_SPEED_MPS) / 2  # between the thresholds: still sliding
    assert ss.update(pos, rot, vel, omega) == [] and ss.sliding.any()
    vel[2, 0] = 0.5 * STICK_SPEED_MPS
    assert ss.update(pos, rot, vel, omega) and not ss.sliding.any()


def test_a_turning_body_slides_at_its_contact_point_not_at_its_centre():
    """A bundle spinning about a horizontal axis through its centre moves its underside,
    0.165 m below, at w x 0.165 m: it slides from w = 2 mm/s / 0.165 m on. A bundle rolling
    on its support (its centre moving at w x 0.165 m, so that its underside stands still)
    does not slide."""
    ss = StickSlip(unit(1).layout())
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    on_its_support = [c.body == 2 for c in ss.resting]
    for share, slides in ((0.8, False), (1.2, True)):
        omega[2, 1] = share * SLIP_SPEED_MPS / 0.165      # rad/s about y
        ss.stick_all()
        ss.update(pos, rot, vel, omega)
        assert ss.sliding[on_its_support].all() == slides, share
    omega[2, 1] = 0.1                                     # the underside at -16.5 mm/s ...
    vel[2, 0] = 0.1 * 0.165                               # ... which rolling keeps still
    ss.stick_all()
    assert ss.update(pos, rot, vel, omega) == []


def test_a_unit_turning_as_one_body_slides_nowhere_but_a_pallet_turning_under_it_does():
    """Turning about the pallet's vertical axis at 0.01 rad/s: carried rigidly (each bundle's
    velocity w x r), no contact moves relative to its other body. Bundles left standing while
    the pallet turns slide at w times their distance from the axis: those beyond 0.2 m exceed
    the 2 mm/s slip speed, the others stick."""
    layout = unit(1).layout()
    ss = StickSlip(layout)
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    pallet = 1
    pos[pallet] = (0.0, 0.0, layout.pallet_size_m[2] / 2)
    pos[2:] = [b.centre_m for b in layout.bundles]
    turn = np.array([0.0, 0.0, 0.01])
    omega[pallet:] = turn
    vel[2:] = np.cross(turn, pos[2:] - pos[pallet])
    assert ss.update(pos, rot, vel, omega) == [] and not ss.sliding.any()
    vel[2:], omega[2:] = 0.0, 0.0
    ss.update(pos, rot, vel, omega)
    on_pallet = [k for k, c in enumerate(ss.resting) if c.other == pallet]
    far = [0.01 * np.hypot(*pos[ss.resting[k].body, :2]) > SLIP_SPEED_MPS for k in on_pallet]
    assert ss.sliding[on_pallet].tolist() == far and any(far) and not all(far)
    assert not ss.sliding[[k for k, c in enumerate(ss.resting) if c.body == pallet]].any()


def test_side_contacts_are_neighbours_in_a_layer_face_to_face_within_a_centimetre():
    """Four 0.28 x 0.19 m bundles in two rows: 5 mm apart along x (side contacts), 20 mm
    apart along y (too far to press on each other), and diagonal neighbours touch no face."""
    x, y = 0.285 / 2, 0.21 / 2
    layout = LoadUnit.from_dict({
        "name": "rows", "pallet": {"preset": "EUR"},
        "bundle": {"length_m": 0.28, "width_m": 0.19, "height_m": 0.33, "mass_kg": 9.0},
        "stack": {"layers": 2, "pattern": "explicit",
                  "positions": [[-x, -y], [x, -y], [-x, y], [x, y]]}}).layout()
    scene = BenchScene(layout)
    side = {frozenset((scene.bodies[c.body].name, scene.bodies[c.other].name))
            for c in _side_contacts(scene)}
    assert side == {frozenset((f"L{n}C1R1", f"L{n}C2R1")) for n in (1, 2)} | {
        frozenset((f"L{n}C1R2", f"L{n}C2R2")) for n in (1, 2)}


def test_one_layer_s_neighbours_meet_the_bundle_on_bundle_value_with_the_freedom_left():
    """On one layer the resting contacts leave the bundles' common coefficient free (the sled's
    and the pallet's trade against each other): it is set so that face-to-face neighbours,
    each m = sqrt(0.3), press on each other at the bundle-bundle value."""
    ss = StickSlip(unit(1).layout())
    mu = ss.coefficients()
    side = _side_contacts(ss.scene)
    assert side and all(mu[c.body] * mu[c.other] == pytest.approx(0.3, rel=1e-4) for c in side)
    assert products(ss)[(1, 0)] == pytest.approx(FRICTION.sled_pallet.static)  # still met


def test_an_interlocked_stack_meets_its_resting_contacts_by_least_squares():
    """Interlocked layers rest on several bundles each: more contacts than bodies, a least
    squares fit in log m. One value per kind of pair is a consistent system (every bundle
    m = sqrt(bundle_bundle) above the first layer), so the fit meets every contact."""
    interlocked = LoadUnit.from_toml(Path(__file__).resolve().parents[2] / "examples"
                                     / "pet_3layer_interlocked.toml").with_friction(FRICTION)
    ss = StickSlip(interlocked.layout())
    assert len(products(ss)) > ss.n_bodies  # 61 resting pairs, 38 bodies: over-determined
    for (body, other), mu in products(ss).items():
        want = (FRICTION.sled_pallet if (body, other) == (1, 0) else
                FRICTION.pallet_bundle if other == 1 else FRICTION.bundle_bundle).static
        assert mu == pytest.approx(want, rel=1e-9), (body, other)


def test_body_coefficients_do_not_depend_on_how_many_blas_threads_run():
    # a threaded SVD rounds differently with the core count, and one last-bit change of a
    # coefficient changes a whole run: the solve runs on one thread whatever the caller allows
    layout = LoadUnit.from_toml("examples/pet_3layer_columnar.toml").layout()
    coefficients = []
    for threads in (1, 4):
        with threadpool_limits(limits=threads, user_api="blas"):
            coefficients.append(StickSlip(layout).coefficients().tobytes())
    assert coefficients[0] == coefficients[1]


def test_a_unit_rocking_as_one_body_slides_nowhere_wherever_it_stands_on_the_sled():
    """The whole unit turning about a horizontal axis through the middle of the pallet's
    underside, which stands 0.3 m ahead and 0.1 m to the side on the sled: every body moves at
    w x (its centre - that point), so every contact point moves with both of its bodies (the
    pallet's underside, the pivot, stands still on the sled), and nothing slides. The contact
    points are under each body's centre: at the pallet's underside, at each bundle's."""
    layout = unit(2).layout()
    ss = StickSlip(layout)
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    pivot = np.array([0.3, 0.1, 0.0])
    pos[1] = pivot + (0.0, 0.0, layout.pallet_size_m[2] / 2)
    pos[2:] = pivot + [b.centre_m for b in layout.bundles]
    w = np.array([0.09, 0.15, 0.0])                 # 0.17 rad/s: its top at ~19 cm/s
    omega[1:] = w
    vel[1:] = np.cross(w, pos[1:] - pivot)
    assert ss.update(pos, rot, vel, omega) == [] and not ss.sliding.any()
    vel[2:], omega[2:] = 0.0, 0.0   # the bundles held still: they slide on the pallet only
    ss.update(pos, rot, vel, omega)
    assert ss.sliding.tolist() == [c.other == 1 for c in ss.resting]


def test_the_moving_bodies_states_are_read_with_the_sled_at_rest_at_its_origin():
    layout = unit(2).layout()
    ss, full = StickSlip(layout), StickSlip(layout)
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    vel[3, 0] = 2 * SLIP_SPEED_MPS
    moving = ss.scene.moving
    assert moving.tolist() == list(range(1, ss.n_bodies))
    assert ss.update_moving(pos[moving], rot[moving], vel[moving], omega[moving]) == \
        full.update(pos, rot, vel, omega) != []
    assert ss.sliding.tolist() == full.sliding.tolist()


def _rows(positions: list[list[float]]) -> set[frozenset[str]]:
    """The side contacts of one layer of 0.28 x 0.19 m bundles at `positions`, by name."""
    layout = LoadUnit.from_dict({
        "name": "rows", "pallet": {"preset": "EUR"},
        "bundle": {"length_m": 0.28, "width_m": 0.19, "height_m": 0.33, "mass_kg": 9.0},
        "stack": {"layers": 1, "pattern": "explicit", "positions": positions}}).layout()
    scene = BenchScene(layout)
    return {frozenset((scene.bodies[c.body].name, scene.bodies[c.other].name))
            for c in _side_contacts(scene)}


def test_bundles_that_touch_only_at_a_corner_or_stand_apart_along_a_row_press_on_no_face():
    x, y = 0.285 / 2, 0.195 / 2           # 5 mm apart along x and along y
    assert _rows([[-x, -y], [x, y]]) == set()                 # corner to corner
    # a row of three, the third 2 cm from the second: only the first two touch
    assert _rows([[-x, -y], [x, -y], [x + 0.3, -y]]) == {frozenset(("L1C1R1", "L1C2R1"))}


def test_a_single_column_has_no_side_contacts_and_gets_its_values_exactly():
    column = LoadUnit.from_dict({
        "name": "column", "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 3, "pattern": "explicit", "positions": [[0.0, 0.0]]},
    }).with_friction(FRICTION)
    ss = StickSlip(column.layout())
    assert _side_contacts(ss.scene) == []
    assert sorted(round(v, 9) for v in products(ss).values()) == [0.3, 0.3, 0.45, 0.5]

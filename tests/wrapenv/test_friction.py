"""Per-pair static and kinetic friction on Bullet's one multiplied coefficient per body
(wrapenv/friction.py): the solve for body coefficients, and the contact states that pick
static or kinetic values with hysteresis."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wrapenv.friction import SLIP_SPEED_MPS, STICK_SPEED_MPS, StickSlip
from wrapenv.load import Friction, FrictionPair, LoadUnit

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
    """A bundle spinning about a horizontal axis through its centre moves its underside."""
    ss = StickSlip(unit(1).layout())
    pos, rot, vel, omega = at_rest(ss.n_bodies)
    omega[2, 1] = 0.1  # rad/s about y: the bottom face (0.165 m below) moves at 16.5 mm/s
    ss.update(pos, rot, vel, omega)
    assert ss.sliding[[c.body == 2 for c in ss.resting]].all()


def test_an_interlocked_stack_meets_its_resting_contacts_by_least_squares():
    """Interlocked layers rest on several bundles each: more contacts than bodies, a least
    squares fit in log m. One value per kind of pair is a consistent system (every bundle
    m = sqrt(bundle_bundle) above the first layer), so the fit meets every contact."""
    interlocked = LoadUnit.from_toml(Path(__file__).resolve().parents[2] / "examples"
                                     / "pet_3layer_interlocked.toml").with_friction(FRICTION)
    ss = StickSlip(interlocked.layout())
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

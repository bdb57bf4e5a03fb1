"""The soft wrap (issue 3, "Must show"): what the envelope does to a load on the bench.

Element and ring tests check the model's laws directly; bench tests check that the wrapped unit
responds to layers, tension, yield, tearing and the bottom band the way a real envelope does.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from wrapenv.bench import Push, run_level
from wrapenv.eumos import WRAP_TORN, evaluate
from wrapenv.load import FrictionPair, LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_elements import element_set
from wrapenv.wrap_physics import WrapNet

EXAMPLE_3 = "examples/pet_3layer_columnar.toml"
EXAMPLE_2 = "examples/pet_2layer_columnar.toml"
#: Differences smaller than this are solver noise (a squeezed stack jitters by ~1 mm).
MONOTONE_TOLERANCE_M = 0.002


def wrap_format(material, bands, web=0.5) -> WrapFormat:
    """bands: (from_m, to_m, layers, tension_n); material: a card name or a custom table."""
    return WrapFormat.from_dict({
        "material": material, "web_width_m": web,
        "band": [dict(from_m=a, to_m=b, layers=n, tension_n=t) for a, b, n, t in bands],
    })


def custom(stiffness, yield_strain, break_strain=2.0, hardening_ratio=0.05) -> dict:
    return dict(grammage_kg_m2=0.05, stiffness_n_per_m=stiffness, yield_strain=yield_strain,
                break_strain=break_strain, hardening_ratio=hardening_ratio)


def one_layer(positions=None, pallet_bundle=(0.3, 0.23)) -> LoadUnit:
    stack = {"layers": 1}
    if positions is not None:
        stack.update(pattern="explicit", positions=positions)
    return LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"}, "stack": stack,
        "friction": {"pallet_bundle": dict(zip(("static", "kinetic"), pallet_bundle,
                                               strict=True))},
        "fixture": {"pallet_stopper": True},
    })


def rest_state(layout):
    """Body positions and rotations of a layout as stacked (pallet first)."""
    pos = np.array([(0, 0, layout.pallet_size_m[2] / 2)] + [b.centre_m for b in layout.bundles])
    return pos, np.repeat(np.eye(3)[None], len(pos), axis=0)


# -- the element law ----------------------------------------------------------------------


def element(k=1000.0, yield_n=10.0, break_n=50.0, hardening=0.1):
    """One element whose web has stiffness k and yield/break forces for one metre of web."""
    return element_set(k_web=np.array([k]), material_strength=(yield_n, break_n, hardening),
                       web_metres=np.array([1.0]), pretension=np.zeros(1), mass=np.ones(1),
                       height=np.zeros(1), length=np.ones(1), give=1e12)


def test_element_is_elastic_below_yield_and_never_pushes():
    e = element()
    assert e.force(np.array([0.005]), np.zeros(1))[0] == pytest.approx(5.0, rel=1e-6)
    assert e.force(np.array([-0.01]), np.zeros(1))[0] == 0.0  # compressed: slack, no push
    assert e.plastic[0] == 0.0


def test_strain_past_yield_leaves_permanent_stretch():
    e = element(k=1000.0, yield_n=10.0, hardening=0.1)
    loaded = e.force(np.array([0.02]), np.zeros(1))[0]
    # bilinear: 10 N at 0.01 m, then 100 N/m more: 11 N at 0.02 m
    assert loaded == pytest.approx(11.0, rel=1e-6)
    assert e.force(np.array([0.0]), np.zeros(1))[0] == 0.0   # back at the start: slack
    # it takes the permanent stretch (0.02 - 11/1000 = 0.009 m) before it pulls again
    assert e.force(np.array([0.009]), np.zeros(1))[0] == pytest.approx(0.0, abs=1e-6)
    assert e.force(np.array([0.010]), np.zeros(1))[0] == pytest.approx(1.0, rel=1e-6)


def test_element_tears_at_its_breaking_force_and_stays_torn():
    e = element(k=1000.0, yield_n=10.0, break_n=12.0, hardening=0.1)
    assert e.force(np.array([0.05]), np.zeros(1))[0] == 0.0
    assert e.torn[0]
    assert e.force(np.array([0.001]), np.zeros(1))[0] == 0.0


# -- rings --------------------------------------------------------------------------------


def test_ring_pretension_is_the_wrapping_tension_of_the_layers_over_its_height():
    layout = one_layer().layout()
    # two bands overlapping over the whole layer: 1 + 2 layers of 100 N on a 0.5 m web
    wrap = wrap_format("kraft", [(0.0, 0.474, 1, 100.0), (0.144, 0.474, 2, 100.0)])
    net = WrapNet(wrap, layout)
    share = 0.33 / 2  # each of the layer's two rings stands for half the layer
    assert net.rings.pretension[1:] == pytest.approx([3 * 100.0 / 0.5 * share] * 2)
    assert net.rings.pretension[0] == pytest.approx(1 * 100.0 / 0.5 * 0.144)  # pallet round


def test_ring_squeezes_the_corners_inward_and_leaves_the_face_bundles_alone():
    layout = one_layer().layout()
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 2, 250.0)]), layout)
    pos, rot = rest_state(layout)
    force, _ = net.forces(pos, rot, np.zeros_like(pos), np.zeros_like(pos))
    assert np.allclose(force.sum(axis=0), 0.0, atol=1e-6)  # the wrap is internal to the unit
    for k, b in enumerate(layout.bundles, start=1):
        x, y = b.centre_m[:2]
        corner = abs(x) > 0.4 and abs(y) > 0.25
        if corner:
            assert force[k, 0] * x < 0 and force[k, 1] * y < 0, b.name  # pushed inward
        else:
            assert np.linalg.norm(force[k, :2]) < 1e-6, b.name


def test_ring_holds_a_bundle_that_bulges_out_and_never_pulls_one_that_moves_in():
    layout = one_layer().layout()
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 2, 250.0)]), layout)
    pos, rot = rest_state(layout)
    face = next(k for k, b in enumerate(layout.bundles, start=1)
                if b.name == "L1C2R1")  # front row (smallest y), not a corner
    zero = np.zeros_like(pos)
    out, inward = pos.copy(), pos.copy()
    out[face, 1] -= 0.01
    inward[face, 1] += 0.01
    net.forces(out, rot, zero, zero)
    assert net.forces(out, rot, zero, zero)[0][face, 1] > 1.0      # pushed back in
    assert np.linalg.norm(net.forces(inward, rot, zero, zero)[0][face]) < 1e-9


def test_without_a_band_on_the_pallet_the_wrap_is_not_anchored():
    layout = one_layer().layout()
    anchored = WrapNet(wrap_format("kraft", [(0.0, 0.474, 1, 250.0)]), layout)
    floating = WrapNet(wrap_format("kraft", [(0.2, 0.474, 1, 250.0)]), layout)
    def touches_pallet(net):
        return bool(np.any(net.node_body[net.panel_nodes] == 0))

    assert touches_pallet(anchored)
    assert 0 not in floating.node_body and not touches_pallet(floating)


# -- the wrapped unit on the bench ---------------------------------------------------------


def middle_push(tension_n: float | None) -> float:
    """Sideways displacement of the middle of three bundles in a row under a 36 N push."""
    layout = one_layer([[-0.282, 0.0], [0.0, 0.0], [0.282, 0.0]]).layout()
    wrap = None if tension_n is None else wrap_format("kraft", [(0.0, 0.474, 1, tension_n)])
    # 36 N = 1.3 x the static friction under the bundle (0.3 x 9.3 kg x g)
    push = Push(layout.bundles[1].name, (0.0, 36.0))
    trace = run_level(layout, PulseProfile(0.01), wrap=wrap, push=push)
    return float(np.ptp(trace.bundle_pos[:, 1, 1]))


def test_pretension_squeezes_a_layer_so_it_resists_a_larger_push():
    unwrapped = middle_push(None)
    slack = middle_push(5.0)      # barely tensioned: the neighbours hardly press on it
    wrapped = middle_push(250.0)  # 250 N web tension: ~80 N squeeze per ring
    assert unwrapped > 0.10       # slides away
    assert slack > 0.02           # held only where it bulges out of the envelope
    assert wrapped < 0.005        # held by friction against its squeezed neighbours


def elastic_max(load: LoadUnit, wrap: WrapFormat, level_g: float) -> float:
    return evaluate(run_level(load.layout(), PulseProfile(level_g), wrap=wrap)).elastic_max_m


@pytest.mark.parametrize("vary", ["layers", "tension"])
def test_more_layers_or_more_tension_give_smaller_displacement(vary):
    """3-layer example at 0.4 g (its pallet holds on the sled), LLDPE over the whole height."""
    load = LoadUnit.from_toml(EXAMPLE_3)
    h = load.load_height_m
    if vary == "layers":
        formats = [wrap_format("lldpe", [(0.0, h, n, 70.0)]) for n in (1, 2, 4)]
    else:
        formats = [wrap_format("lldpe", [(0.0, h, 2, t)]) for t in (20.0, 70.0, 130.0)]
    disp = [elastic_max(load, w, 0.4) for w in formats]
    assert all(b <= a + MONOTONE_TOLERANCE_M for a, b in zip(disp, disp[1:], strict=False)), disp
    assert disp[-1] < disp[0] / 2, disp


def slick_two_layers() -> LoadUnit:
    """The 2-layer example with a slippery pallet deck (0.2/0.15) and a stopper behind it."""
    load = LoadUnit.from_toml(EXAMPLE_2)
    friction = replace(load.friction, pallet_bundle=FrictionPair(0.2, 0.15))
    return replace(load.with_friction(friction), pallet_stopper=True)


def test_strain_past_break_tears_the_wrap_and_fails_the_verdict():
    weak = custom(4e4, yield_strain=0.002, break_strain=0.004, hardening_ratio=0.5)
    trace = run_level(slick_two_layers().layout(), PulseProfile(0.5),
                      wrap=wrap_format(weak, [(0.0, 0.804, 1, 20.0)]))
    verdict = evaluate(trace)
    assert trace.wrap.torn and trace.wrap.torn_at_m
    assert WRAP_TORN in verdict.damage
    assert not verdict.passed and not verdict.criteria["no_damage"]
    assert verdict.to_json()["wrap"]["torn"] is True


def test_strain_past_yield_leaves_permanent_displacement_after_the_pulse():
    """One bundle tethered to the pallet by the wrap; a gentle stop (0.04 g, below the 0.08 g
    kinetic friction) so nothing but the wrap brings it back."""
    load = one_layer([[0.0, 0.0]], pallet_bundle=(0.1, 0.08))
    profile = PulseProfile(0.4, decel_ratio=0.1)
    results = {}
    for name, yield_strain in (("yielding", 0.005), ("elastic", 1.0)):
        wrap = wrap_format(custom(2e3, yield_strain), [(0.0, 0.474, 1, 1.0)])
        trace = run_level(load.layout(), profile, wrap=wrap)
        results[name] = (evaluate(trace).permanent_max_m, trace.wrap.plastic_strain_max)
    assert results["yielding"][1] > 0.01 and results["elastic"][1] == 0.0
    assert results["yielding"][0] > 5 * results["elastic"][0]
    assert results["yielding"][0] > 0.01


def test_three_layer_example_fails_unwrapped_where_the_example_wraps_pass():
    load = LoadUnit.from_toml(EXAMPLE_3)
    assert not evaluate(run_level(load.layout(), PulseProfile(0.3))).passed
    for path in ("examples/wrap_kraft_3layer.toml", "examples/wrap_lldpe_3layer.toml"):
        wrap = WrapFormat.from_toml(path, load.load_height_m)
        verdict = evaluate(run_level(load.layout(), PulseProfile(0.3), wrap=wrap))
        assert verdict.passed, (path, verdict)
        assert not verdict.wrap.torn


def test_the_anchored_bottom_band_keeps_the_lowest_20_cm_in_place():
    load = slick_two_layers()
    with_bottom = wrap_format("kraft", [(0.0, 0.45, 3, 250.0), (0.45, 0.804, 1, 250.0)])
    without = wrap_format("kraft", [(0.25, 0.804, 2, 250.0)])
    low = {}
    for name, wrap in (("with", with_bottom), ("without", without)):
        low[name] = evaluate(run_level(load.layout(), PulseProfile(0.5), wrap=wrap))
    assert low["with"].permanent_low20_m < 0.04 and low["with"].criteria["low20_4cm"]
    assert low["without"].permanent_low20_m >= 0.04 and not low["without"].criteria["low20_4cm"]


def test_wrapped_runs_are_deterministic():
    layout = one_layer().layout()
    wrap = wrap_format("kraft", [(0.0, 0.474, 2, 250.0)])
    a = run_level(layout, PulseProfile(0.5), wrap=wrap)
    b = run_level(layout, PulseProfile(0.5), wrap=wrap)
    assert np.array_equal(a.bundle_pos, b.bundle_pos) and a.wrap == b.wrap

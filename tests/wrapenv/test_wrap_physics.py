"""The soft wrap (issues 3 and 12, "Must show"): what the envelope does to a load on the bench.

Element and ring tests check the model's laws directly, against hand computations; bench tests
check that the wrapped unit responds to layers, tension, yield, tearing, the bottom band, the
load's give and the seam the way a real envelope does, and that the most loaded places are
where mechanics says they are.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.wrapenv.conftest import kraft_example, slick_two_layers, weak_wrap_on_a_slick_unit
from wrapenv import bench
from wrapenv.bench import Push, SimSettings, run_level, run_levels
from wrapenv.eumos import WRAP_OPENED, WRAP_TORN, evaluate
from wrapenv.load import Bundle, Friction, FrictionPair, LoadUnit, Pallet, Stack
from wrapenv.material import MATERIALS
from wrapenv.profile import PulseProfile
from wrapenv.program import Program, Reinforcement
from wrapenv.uncertainty import Sample
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import PALLET_CORNER_STIFFNESS_N_PER_M2, WrapNet

EXAMPLE_3 = "examples/pet_3layer_columnar.toml"
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
    stack: dict[str, Any] = {"layers": 1}
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


# -- rings --------------------------------------------------------------------------------


def test_ring_pretension_is_the_wrapping_tension_of_the_layers_over_its_height():
    layout = one_layer().layout()
    # two bands overlapping over the whole layer: 1 + 2 layers of 100 N on a 0.5 m web
    wrap = wrap_format("kraft", [(0.0, 0.474, 1, 100.0), (0.144, 0.474, 2, 100.0)])
    net = WrapNet(wrap, layout)
    share = 0.33 / 2  # each of the layer's two rings stands for half the layer
    assert net.rings.pretension_n[1:] == pytest.approx([3 * 100.0 / 0.5 * share] * 2)
    assert net.rings.pretension_n[0] == pytest.approx(1 * 100.0 / 0.5 * 0.144)  # pallet round


def test_a_ring_lies_round_its_layer_wherever_the_layer_stands_on_the_pallet():
    """Four bundles 0.28 x 0.19 m, 2 x 2 face to face, once centred and once 0.3 m forward and
    0.1 m to the side on the pallet: each ring round them is 2 (0.56 + 0.38) = 1.88 m long,
    and it presses each bundle towards the layer's own centre."""
    for dx, dy in ((0.0, 0.0), (0.3, 0.1)):
        layout = one_layer([[dx + sx * 0.14, dy + sy * 0.095]
                            for sx in (-1, 1) for sy in (-1, 1)]).layout()
        net = WrapNet(wrap_format("kraft", [(0.144, 0.474, 1, 250.0)]), layout)
        pos, rot = rest_state(layout)
        net.freeze(pos, rot)
        assert net.rings.rest_m + net.rings.pretension_n / net.rings.k_elastic_n_per_m \
            == pytest.approx([1.88, 1.88])
        force, _ = net.forces(pos, rot, np.zeros_like(pos), np.zeros_like(pos))
        inward = np.array([dx, dy]) - pos[1:, :2]
        assert np.all(np.einsum("bk,bk->b", force[1:, :2], inward) > 0)


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


def two_layer_kraft() -> tuple[WrapNet, Any]:
    """The 2-layer example under its Kraft wrap, frozen on the unit as stacked."""
    load, wrap = kraft_example()
    layout = load.layout()
    net = WrapNet(wrap, layout)
    net.freeze(*rest_state(layout))
    return net, layout


def test_the_wrap_s_forces_are_internal_to_the_unit_however_it_is_deformed():
    """Every element pulls its two ends together: the wrap adds no net force and no net torque
    to the unit, one wrench per body (the pallet and each bundle), whatever the bodies do."""
    net, layout = two_layer_kraft()
    pos, rot = rest_state(layout)
    rng = np.random.default_rng(3)
    pos = pos + rng.normal(0.0, 0.004, pos.shape)
    vel, omega = rng.normal(0.0, 0.05, pos.shape), rng.normal(0.0, 0.2, pos.shape)
    force, torque = net.forces(pos, rot, vel, omega)
    assert force.shape == torque.shape == (1 + len(layout.bundles), 3)
    assert np.abs(force).max() > 10.0                               # it does pull
    assert np.allclose(force.sum(axis=0), 0.0, atol=1e-6)
    assert np.allclose((np.cross(pos, force) + torque).sum(axis=0), 0.0, atol=1e-6)


def test_a_unit_moving_as_one_body_stretches_no_element_and_damps_nothing():
    """The top layer pushed 4 mm forward (the wrap's panels taut), then the whole unit carried
    along at 0.3 m/s and turning at 0.19 rad/s as one rigid body: its elements keep their
    lengths, so the wrap pulls as it does on the unit held still there."""
    still, layout = two_layer_kraft()
    moving, _ = two_layer_kraft()
    pos, rot = rest_state(layout)
    pos[1:] += [(0.004, 0.0, 0.0) if b.layer == 2 else (0.0, 0.0, 0.0) for b in layout.bundles]
    w = np.array([0.1, -0.05, 0.15])
    vel = np.array([0.3, 0.0, 0.0]) + np.cross(w, pos - pos[0])
    zero = np.zeros_like(pos)
    at_rest = still.forces(pos, rot, zero, zero)
    carried = moving.forces(pos, rot, vel, np.broadcast_to(w, pos.shape))
    assert (moving.panels.last_n > 0).any() and moving.panels.damping_n_s_per_m.min() > 0
    for a, b in zip(at_rest, carried, strict=True):
        assert b == pytest.approx(a, abs=1e-9)


def test_a_panel_pulls_its_ends_together_with_its_tension():
    """One bundle on the pallet under one Kraft layer: each ring lies on one body, so the
    bundle's net force is the panels' alone, each pulling it towards the pallet's round along
    the panel with the tension it bears."""
    layout = one_layer([[0.0, 0.0]]).layout()
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 1, 250.0)]), layout)
    pos, rot = rest_state(layout)
    net.freeze(pos, rot)
    lifted = pos.copy()
    lifted[1] += (0.003, -0.002, 0.004)
    zero = np.zeros_like(pos)
    force, _ = net.forces(lifted, rot, zero, zero)
    nodes = net.nodes(lifted, rot)
    a, b = net.panel_nodes.T
    along = nodes[b] - nodes[a]
    unit = along / np.linalg.norm(along, axis=1)[:, None]
    assert np.all(net.node_body[a] == 0) and np.all(net.node_body[b] == 1)
    assert net.panels.last_n.max() > 1.0
    assert force[1] == pytest.approx(-(net.panels.last_n[:, None] * unit).sum(axis=0))


def test_while_it_is_laid_the_wrap_squeezes_with_the_share_of_its_tension_laid_so_far():
    layout = one_layer().layout()
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 1, 250.0)]), layout)
    pos, rot = rest_state(layout)
    zero = np.zeros_like(pos)
    pulls = []
    for fraction in (-0.5, 0.5, 1.0, 2.0):       # clipped to what can be laid
        net.laying(fraction)
        pulls.append(np.abs(net.forces(pos, rot, zero, zero)[0][1:]).sum())   # on the corners
    assert pulls[0] == 0.0 and pulls[2] > 0.0
    assert pulls[1] == pytest.approx(pulls[2] / 2) and pulls[3] == pytest.approx(pulls[2])


def test_a_later_level_reports_its_own_peaks_on_the_wrap_it_inherited():
    net, layout = two_layer_kraft()
    pos, rot = rest_state(layout)
    zero = np.zeros_like(pos)
    net.forces(pos * 1.01, rot, zero, zero, t_s=0.1)
    net.ring_edge[:] = 0.9
    assert net.rings.peak.max() > 0 and net.seam_peak > 0
    rest = (net.rings.rest_m.copy(), net.panels.plastic_m.copy())
    net.next_level()
    assert net.rings.peak.max() == 0.0 and net.panels.peak.max() == 0.0
    assert net.rings.peak_force_n.max() == 0.0 == net.panels.peak_force_n.max()
    assert np.isnan(net.rings.peak_t_s).all()
    assert np.all(net.ring_edge == 1.0)
    assert (net.seam_peak, net.seam_peak_force) == (0.0, 0.0) and math.isnan(net.seam_peak_t)
    assert net.rings.rest_m == pytest.approx(rest[0])            # what it was stretched to
    assert net.panels.plastic_m == pytest.approx(rest[1])


# -- the load's give ----------------------------------------------------------------------

KRAFT = MATERIALS["kraft"]


def test_a_ring_has_its_corners_dents_in_series_with_its_web():
    """A ring of tension T pushes each 90-degree corner with 2 T sin(45°) = 1.41 T; the corner
    dents by that over k = corner stiffness x ring height, which shortens the perimeter by
    2 sin(45°) x dent = 2 T / k per corner: 8 T / k for four, in series with the web's
    K x web metres / perimeter."""
    layout = one_layer().layout()
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 2, 250.0)]), layout)
    lx, ly = layout.outline_m
    h = 0.165                                  # each ring of the 0.33 m layer: half of it
    web = KRAFT.stiffness_n_per_m * 2 * h / (2 * (lx + ly))
    give = 6.0e5 * h / 8                       # the PET bundle's 6e5 N/m per m of edge
    assert net.rings.k_elastic_n_per_m[1] == pytest.approx(1 / (1 / web + 1 / give), rel=1e-6)
    pallet_give = PALLET_CORNER_STIFFNESS_N_PER_M2 * 0.144 / 8
    pallet_web = KRAFT.stiffness_n_per_m * 2 * 0.144 / 4.0      # EUR pallet: 4.0 m round
    assert net.rings.k_elastic_n_per_m[0] == pytest.approx(1 / (1 / pallet_web + 1 / pallet_give),
                                                   rel=1e-6)


def test_a_panel_has_the_give_of_both_its_ends():
    layout = one_layer([[0.0, 0.0]]).layout()   # one bundle: panels from the pallet round only
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 1, 250.0)]), layout)
    e = net.panel_spec.where.index("corner -x-y")
    ends = 1 / (1 / (PALLET_CORNER_STIFFNESS_N_PER_M2 * 0.144) + 1 / (6.0e5 * 0.165))
    web = net.panel_spec.k_web_n_per_m[e]
    assert net.panels.k_elastic_n_per_m[e] == pytest.approx(1 / (1 / web + 1 / ends), rel=1e-6)


def test_the_card_s_shear_ratio_stiffens_the_face_diagonals_and_its_damping_ratio_every_element():
    """A panel across a face takes shear as `shear_ratio` of the web's stiffness (docs/
    materials.md, section 8), a corner vertical as the web itself; each element is damped at
    `damping_ratio` of critical, 2 ratio sqrt(k m)."""
    layout = one_layer([[0.0, 0.0]]).layout()
    wrap = wrap_format("kraft", [(0.0, 0.474, 1, 250.0)])
    base = WrapNet(wrap, layout)
    card = replace(wrap.material, shear_ratio=2 * wrap.material.shear_ratio,
                   damping_ratio=2 * wrap.material.damping_ratio)
    other = WrapNet(replace(wrap, material=card), layout)
    where = base.panel_spec.where
    faces = [i for i, w in enumerate(where) if w.startswith("face")]
    corners = [i for i, w in enumerate(where) if w.startswith("corner")]
    assert faces and corners
    k_other, k_base = other.panel_spec.k_web_n_per_m, base.panel_spec.k_web_n_per_m
    assert k_other[faces] == pytest.approx(2 * k_base[faces])
    assert k_other[corners] == pytest.approx(k_base[corners])
    assert other.rings.k_elastic_n_per_m == pytest.approx(base.rings.k_elastic_n_per_m)
    assert other.rings.damping_n_s_per_m == pytest.approx(2 * base.rings.damping_n_s_per_m)
    stiffer = other.panels.k_elastic_n_per_m / base.panels.k_elastic_n_per_m
    assert other.panels.damping_n_s_per_m == pytest.approx(
        2 * np.sqrt(stiffer) * base.panels.damping_n_s_per_m)


def test_a_softer_product_makes_every_element_on_it_softer_and_none_stiffer_than_the_web():
    """Every panel has a bundle at one end at least; of the rings, the pallet round bears on
    the pallet alone and does not change."""
    load = one_layer()
    wrap = wrap_format("kraft", [(0.0, 0.474, 2, 250.0)])
    nets = [WrapNet(wrap, load.with_give(scale).layout()) for scale in (0.5, 1.0, 2.0)]
    for elements, on_bundles in (("rings", slice(1, None)), ("panels", slice(None))):
        k = [getattr(n, elements).k_elastic_n_per_m[on_bundles] for n in nets]
        assert np.all(k[0] < k[1]) and np.all(k[1] < k[2]), elements
    assert len({float(n.rings.k_elastic_n_per_m[0]) for n in nets}) == 1
    assert np.all(nets[2].panels.k_elastic_n_per_m < nets[2].panel_spec.k_web_n_per_m)


# -- paper's layers slide, film's cling ------------------------------------------------------


def frozen_at_rest(net: WrapNet, layout) -> None:
    """Lay the wrap on the unit as stacked and take one step: every ring at its pretension."""
    pos, rot = rest_state(layout)
    net.freeze(pos, rot)
    zero = np.zeros_like(pos)
    net.forces(pos, rot, zero, zero)


def test_paper_layers_outside_the_first_bear_only_what_friction_passes_them():
    """One bundle on the pallet, 3 Kraft layers at 250 N. The vertical at the -x-y corner runs
    from the pallet's corner to the bundle's. Each end's ring pushes that corner with
    sqrt(2) x its tension; 2 of its 3 layers are outside the first and press on it with 2/3 of
    that, shared by the 3 panels ending at the corner (the vertical and two diagonals). The
    weaker end is the pallet round's (0.144 m of web against 0.165): its tension 3 x 250 N /
    0.5 m x 0.144 m = 216 N. Friction 0.4 on that press carries the vertical's vertical part:
    grip = 0.4 x sqrt(2) x 216 x 2/3 / 3 / rise. The panel bears one layer's break force plus
    that grip."""
    layout = one_layer([[0.0, 0.0]]).layout()
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 3, 250.0)]), layout)
    frozen_at_rest(net, layout)
    e = net.panel_spec.where.index("corner -x-y")
    run = np.array([0.6 - 0.14, 0.4 - 0.095, 0.2265 - 0.072])   # pallet corner to bundle's
    rise = run[2] / np.linalg.norm(run)
    grip = 0.4 * math.sqrt(2) * 216.0 * (2 / 3) / 3 / rise
    all_layers = KRAFT.break_force_n_per_m * net.panel_spec.web_m[e]
    assert net.panels.break_force_n[e] == pytest.approx(all_layers / 3 + grip, rel=1e-3)
    assert net.panels.break_force_n[e] < all_layers
    # the layers act together until the outer two's share, 2/3 of the panel's force, reaches
    # the grip: it yields at 3/2 of it (below the web's own yield here); past that only the
    # inner layer stretches, a third of the web behind the give of the panel's ends
    all_yield = KRAFT.yield_force_n_per_m * net.panel_spec.web_m[e]
    assert 1.5 * grip < all_yield
    assert net.panels.yield_force_n[e] == pytest.approx(1.5 * grip, rel=1e-3)
    k_el, k_web_n_per_m = net.panels.k_elastic_n_per_m[e], net.panel_spec.k_web_n_per_m[e]
    give = 1 / (1 / k_el - 1 / k_web_n_per_m)
    h = net.panels.plastic_modulus_n_per_m[e]
    assert k_el * h / (k_el + h) == pytest.approx(1 / (3 / k_web_n_per_m + 1 / give), rel=1e-6)


def test_paper_layers_that_grip_harder_than_they_yield_act_together_until_the_web_yields():
    """A coated paper whose layers grip at 2.0, the same card as film (clinging) otherwise,
    3 layers at 1200 N round one bundle. Pressed that hard, the outer layers' grip on the
    vertical at the -x-y corner exceeds their share of the web's own yield force: the panel
    yields and hardens as the clinging web's, all layers at once. It still tears sooner: the
    outer layers pass at most their yield share through friction, so it bears one layer's
    breaking force plus 2/3 of the three layers' yield force. At 250 N the same paper's outer
    layers slip first, below the web's yield."""
    layout = one_layer([[0.0, 0.0]]).layout()
    card = {"grammage_kg_m2": 0.09, "stiffness_n_per_m": 4e5, "yield_strain": 0.008,
            "break_strain": 0.07, "hardening_ratio": 0.1125, "thickness_m": 1.3e-4}
    nets = {}
    for key, kind, tension_n in (("tacky", "paper", 1200.0), ("film", "film", 1200.0),
                                 ("light", "paper", 250.0)):
        table = {**card, "kind": kind}
        if kind == "paper":
            table["interlayer_friction"] = 2.0
        nets[key] = WrapNet(wrap_format(table, [(0.0, 0.474, 3, tension_n)]), layout)
        frozen_at_rest(nets[key], layout)
    e = nets["tacky"].panel_spec.where.index("corner -x-y")
    tacky, film = nets["tacky"].panels, nets["film"].panels
    all_yield = 0.008 * 4e5 * nets["tacky"].panel_spec.web_m[e]
    assert tacky.yield_force_n[e] == pytest.approx(all_yield) == film.yield_force_n[e]
    assert tacky.plastic_modulus_n_per_m[e] == pytest.approx(film.plastic_modulus_n_per_m[e])
    assert tacky.break_force_n[e] == pytest.approx(film.break_force_n[e] / 3 + 2 / 3 * all_yield)
    assert nets["light"].panels.yield_force_n[e] < 0.5 * all_yield
    assert nets["light"].panels.plastic_modulus_n_per_m[e] > film.plastic_modulus_n_per_m[e]


def test_film_layers_cling_and_share_every_panel():
    layout = one_layer([[0.0, 0.0]]).layout()
    net = WrapNet(wrap_format("lldpe", [(0.0, 0.474, 3, 70.0)]), layout)
    frozen_at_rest(net, layout)
    film = MATERIALS["lldpe"]
    assert len(net.sliding) == 0
    assert net.panels.break_force_n == pytest.approx(film.break_force_n_per_m
                                                   * net.panel_spec.web_m)


# -- the seam ---------------------------------------------------------------------------


def test_the_seam_is_where_the_last_revolution_lies_and_holds_one_layer_less_the_capstan():
    """The default program ends with 3 top wraps whose web's top is 5 cm above the 3-layer
    load: they cover 0.684 m to the top, the rings at 0.721, 0.886 and 1.051 m. Each ring
    there has at least 2 layers, so the tail's last turn lies on a full turn beneath, and
    friction (0.4) round it takes all but e^(-2 pi 0.4) = 8.1 % of that layer's tension."""
    load = LoadUnit.from_toml(EXAMPLE_3)
    wrap = WrapFormat.from_toml("examples/program_kraft_default.toml", load.load_height_m)
    net = WrapNet(wrap, load.layout())
    assert net.ring_heights[net.seam] == pytest.approx([0.7215, 0.8865, 1.0515])
    layers = np.array([net.ring_specs[i].layers for i in net.seam])
    assert np.all(layers >= 2)
    assert net._seam_share == pytest.approx(math.exp(-2 * math.pi * 0.4) / layers)


def test_a_single_layer_s_seam_holds_that_layer_s_whole_tension():
    layout = one_layer().layout()
    net = WrapNet(wrap_format("kraft", [(0.0, 0.474, 1, 250.0)]), layout)
    assert net._seam_share == pytest.approx([1.0, 1.0, 1.0])   # pallet round and both rings


# -- where a weak card tears ----------------------------------------------------------------

#: Standard (not extensible) sack kraft, breaking at 2.5 % (docs/materials.md, section 1).
STANDARD_KRAFT = dict(kind="paper", grammage_kg_m2=0.09, stiffness_n_per_m=4.0e5,
                      yield_strain=0.008, break_strain=0.025, hardening_ratio=0.1125,
                      cd_ratio=0.6, thickness_m=1.3e-4)


def tear_by_pushing_apart(edge_radius_m: float):
    """Four bundles (2 x 2) under one ring of standard kraft, pushed apart diagonally 0.1 mm at
    a time until the ring tears (no Bullet: the net's own law). Faces stay straight, so the web
    bends only round the four corners. Returns the net and how far the bundles moved."""
    load = LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "stack": {"layers": 1, "pattern": "explicit", "positions": [
            [-0.141, -0.096], [0.141, -0.096], [-0.141, 0.096], [0.141, 0.096]]},
        "bundle": {"preset": "PET6x1.5L", "edge_radius_m": edge_radius_m}})
    layout = load.layout()
    net = WrapNet(wrap_format(STANDARD_KRAFT, [(0.35, 0.474, 2, 100.0)]), layout)
    assert len(net.ring_specs) == 1 and len(net.panel_nodes) == 0   # one ring, nothing else
    pos, rot = rest_state(layout)
    net.freeze(pos, rot)
    zero = np.zeros_like(pos)
    outward = np.zeros_like(pos)
    outward[1:, :2] = np.sign(pos[1:, :2]) / math.sqrt(2)
    for step in range(1, 2000):
        net.forces(pos + outward * 1e-4 * step, rot, zero, zero, t_s=step * 1e-3)
        if net.rings.torn[0]:
            return net, step * 1e-4
    raise AssertionError("the ring never tore")


def test_under_a_weak_card_a_corner_tears_where_the_faces_hold(edge_factor):
    """One tension runs round the ring; where the web turns round a carton's 3 mm edge its
    outer fibre already carries 0.13 / 6.13 = 2.1 % of strain (capped at half the 2.5 % it
    breaks at), so the corners reach their limit while the flat faces, at the same tension,
    are at 1 / edge factor of theirs. Round a bottle's 45 mm side the web bends 16 x less,
    and the same ring tears later, at a tension higher by the ratio of the edge factors."""
    carton, moved_carton = tear_by_pushing_apart(0.003)
    bottle, moved_bottle = tear_by_pushing_apart(0.045)
    card = carton.wrap.material
    for net, radius in ((carton, 0.003), (bottle, 0.045)):
        places = {p.where: p for p in net.report().places if p.element == "ring"}
        torn = sorted(w for w, p in places.items() if p.torn)
        assert torn == ["corner +x+y", "corner +x-y", "corner -x+y", "corner -x-y"]
        for face in ("face -y", "face +x", "face +y", "face -x"):
            assert places[face].utilisation == pytest.approx(1 / edge_factor(card, radius),
                                                             rel=1e-3)
        assert net.rings.peak_force_n[0] == pytest.approx(
            net.rings.break_force_n[0] / edge_factor(card, radius), rel=1e-3)
    assert moved_carton < moved_bottle
    assert bottle.rings.peak_force_n[0] / carton.rings.peak_force_n[0] == pytest.approx(
        edge_factor(card, 0.003) / edge_factor(card, 0.045), rel=1e-3)


# -- the wrapped unit on the bench ---------------------------------------------------------


def row_web(tension_n: float, material: str = "kraft") -> WrapFormat:
    """One web over the layer of `pushed_row`."""
    return wrap_format(material, [(0.0, 0.474, 1, tension_n)])


def pushed_row(web: float | WrapFormat | None) -> np.ndarray:
    """Bundle positions (frames, 3, 3) of three 0.28 m bundles in a row along x, 2 mm apart,
    the middle one pushed sideways with 36 N = 1.3 x its static grip on the pallet
    (0.3 x 9.3 kg x g = 27.4 N); `web` a wrap, a Kraft `row_web`'s tension, or None."""
    layout = one_layer([[-0.282, 0.0], [0.0, 0.0], [0.282, 0.0]]).layout()
    wrap = row_web(web) if isinstance(web, float) else web
    push = Push(layout.bundles[1].name, (0.0, 36.0))
    return run_level(layout, PulseProfile(0.01), wrap=wrap, push=push).bundle_pos_m


def middle_push(web: float | WrapFormat | None) -> float:
    """Sideways displacement of the middle bundle of `pushed_row`."""
    return float(np.ptp(pushed_row(web)[:, 1, 1]))


#: The web tension above which the row's wrap shuts its gaps as it is laid (derived in
#: `test_a_web_squeezes_the_row_only_above_the_tension_whose_pull_beats_the_end_bundles_grip`).
ROW_SQUEEZE_N = 0.3 * 9.3 * 9.81 * 0.5 / (4 * 0.165)


def test_pretension_squeezes_a_layer_so_it_resists_a_larger_push():
    unwrapped = middle_push(None)
    slack = middle_push(5.0)      # barely tensioned: the neighbours hardly press on it
    wrapped = middle_push(250.0)  # 250 N web tension: ~80 N squeeze per ring
    assert unwrapped > 0.10       # slides away
    assert slack > 0.02           # held only where it bulges out of the envelope
    assert wrapped < 0.005        # held by friction against its squeezed neighbours


def test_a_web_squeezes_the_row_only_above_the_tension_whose_pull_beats_the_end_bundles_grip():
    """By hand: each of the layer's two rings stands for 0.165 m of the 0.5 m web, so it holds
    0.33 x the web's tension, and pulls each end bundle inward with 2 x that (its two corners
    there): 4 x 0.33 x T in all, against the end bundle's static grip on the pallet, 27.4 N.
    So the wrap closes the row's 2 mm gaps as it is laid only above T* = 27.4 N x 0.5 m /
    (4 x 0.165 m) = 20.7 N. Just below, the middle bundle is not squeezed, and the push slides
    it as far as under a barely tensioned web; a fifth above, the gaps are shut and it holds."""
    below, above = pushed_row(0.95 * ROW_SQUEEZE_N), pushed_row(1.2 * ROW_SQUEEZE_N)

    def gaps_m(pos: np.ndarray) -> np.ndarray:
        return np.diff(pos[0, :, 0]) - 0.28   # as the level starts, the wrap laid

    assert gaps_m(below) == pytest.approx([0.002, 0.002], abs=1e-4)
    assert gaps_m(above) == pytest.approx([0.0, 0.0], abs=2e-4)  # shut: 0.08 mm into each other
    assert np.ptp(below[:, 1, 1]) == pytest.approx(middle_push(5.0), rel=0.1)
    assert np.ptp(above[:, 1, 1]) < 0.005


def test_film_relaxed_below_that_tension_no_longer_squeezes_the_row_and_above_it_still_does():
    """By hand: film keeps 74 % of its tension after 30 days (Dunno & Symanski, the relaxation
    law's own figure). Laid at 1.2 T* it keeps 0.89 T*, below the squeeze threshold T* of the
    test above: the row's gaps stay open, and the middle bundle, held only where it bulges out
    of the envelope, slides as under a slack web (more than 20 mm, `test_pretension_...`).
    Laid at 1.5 T* it keeps 1.11 T*: the gaps shut and it holds, as the fresh web does at
    either tension."""
    kept = MATERIALS["lldpe"].relaxation.retained(720.0)
    assert kept == pytest.approx(0.74, abs=0.005)
    for laid in (1.2, 1.5):
        web = row_web(laid * ROW_SQUEEZE_N, "lldpe")
        assert middle_push(web) < 0.005, laid
        month = pushed_row(web.relaxed(720.0))
        gaps_m = np.diff(month[0, :, 0]) - 0.28
        if laid * kept < 1.0:
            assert gaps_m == pytest.approx([0.002, 0.002], abs=1e-4)
            assert np.ptp(month[:, 1, 1]) > 0.02
        else:
            assert gaps_m == pytest.approx([0.0, 0.0], abs=2e-4)
            assert np.ptp(month[:, 1, 1]) < 0.005


def elastic_max(load: LoadUnit, wrap: WrapFormat, level_g: float) -> float:
    elastic = evaluate(run_level(load.layout(), PulseProfile(level_g), wrap=wrap)).elastic_max_m
    assert elastic is not None
    return elastic


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


def test_strain_past_break_tears_the_wrap_and_fails_the_verdict():
    load, wrap = weak_wrap_on_a_slick_unit()
    trace = run_level(load.layout(), PulseProfile(0.5), wrap=wrap)
    verdict = evaluate(trace)
    assert trace.wrap.torn and trace.wrap.torn_at_m
    assert WRAP_TORN in verdict.damage
    assert not verdict.passed and not verdict.criteria["no_damage"]
    assert verdict.to_json()["wrap"]["torn"] is True


def tether_pull_n(layout, wrap: WrapFormat, dx_m: float) -> np.ndarray:
    """The wrap's force on the one bundle of `layout`, laid at rest and then the bundle moved
    `dx_m` along x in one go (a monotonic stretch: the plastic part as the pulse leaves it)."""
    net = WrapNet(wrap, layout)
    pos, rot = rest_state(layout)
    net.freeze(pos, rot)
    moved = pos.copy()
    moved[1, 0] += dx_m
    zero = np.zeros_like(pos)
    return net.forces(moved, rot, zero, zero)[0][1]


def test_a_tethered_bundle_sways_as_a_mass_on_a_spring_as_stiff_as_its_layers_make_it():
    """The tethered bundle below, its web elastic, at 0.4 g: by hand a mass on a spring K (the
    tether's slope, probed on the net) under a step push of (0.4 - mu_k) m g, the pulse's
    0.5 s dwell twice its period or more. It sways at least to where static friction alone
    can hold it, (0.4 - mu_s) m g / K, and at most to twice the step's static deflection,
    2 (0.4 - mu_k) m g / K (undamped); between, the same step on a stiffer spring sways less
    as 1 / K (within 10 %: the ramp is a larger part of a shorter period). Each layer adds
    stiffness in parallel, less the give of the bundle's corners in series: up to n x."""
    layout = one_layer([[0.0, 0.0]], pallet_bundle=(0.1, 0.08)).layout()
    mass_kg = layout.bundles[0].mass_kg
    sway_m, k_n_per_m = [], []
    for layers in (1, 2, 4):
        wrap = wrap_format(custom(2e3, 0.5), [(0.0, 0.474, layers, 1.0)])
        k = tether_pull_n(layout, wrap, -0.001)[0] / 0.001
        assert 2 * math.pi * math.sqrt(mass_kg / k) < 0.5 / 2
        trace = run_level(layout, PulseProfile(0.4, decel_ratio=0.1), wrap=wrap)
        sway = -np.min(trace.bundle_pos_m[:, 0, 0] - trace.bundle_pos_m[0, 0, 0])
        assert (0.4 - 0.1) * mass_kg * 9.81 / k <= sway <= 2 * (0.4 - 0.08) * mass_kg * 9.81 / k
        sway_m.append(sway)
        k_n_per_m.append(k)
    assert k_n_per_m[0] < k_n_per_m[1] < k_n_per_m[2] <= 4 * k_n_per_m[0]
    assert [sway / sway_m[0] for sway in sway_m] == pytest.approx(
        [k_n_per_m[0] / k for k in k_n_per_m], rel=0.1)


def test_strain_past_yield_leaves_permanent_displacement_after_the_pulse():
    """One bundle (9.3 kg) tethered to the pallet by one web, on a slick pallet (static 0.10,
    kinetic 0.08): the pulse slides it back; the stop (0.04 g, below either coefficient) never
    pushes it harder than friction resists, so nothing but the wrap brings it back. By hand,
    with the tether's pull P(x) probed on the wrap's net and K its elastic slope:
    - an elastic web is a spring with Coulomb friction: the bundle comes to rest where the
      spring no longer beats static friction, |x_end| <= mu_s (m g + |P_z|) / K (1.4 mm);
    - a yielding web gives back from the peak x_pk only its elastic energy, P(x_pk)^2 / 2K,
      against at least (mu_k - 0.04) m g of friction: the bundle returns at most that energy
      over that force and stays at least |x_pk| - return from home (16 of 28 mm), over ten
      times the elastic web's band."""
    load = one_layer([[0.0, 0.0]], pallet_bundle=(0.1, 0.08))
    layout = load.layout()
    weight_n = layout.bundles[0].mass_kg * 9.81
    profile = PulseProfile(0.4, decel_ratio=0.1)
    for name, yield_strain in (("yielding", 0.005), ("elastic", 0.5)):  # 0.5: a card's most
        wrap = wrap_format(custom(2e3, yield_strain), [(0.0, 0.474, 1, 1.0)])
        trace = run_level(layout, profile, wrap=wrap)
        x_m = trace.bundle_pos_m[:, 0, 0] - trace.bundle_pos_m[0, 0, 0]
        pull = tether_pull_n(layout, wrap, -0.001)
        k_n_per_m = pull[0] / 0.001
        assert tether_pull_n(layout, wrap, 0.001)[0] == pytest.approx(-pull[0], rel=0.01)
        if name == "elastic":
            assert trace.wrap.plastic_strain_max == 0.0
            assert abs(x_m[-1]) <= 0.1 * (weight_n + abs(pull[2])) / k_n_per_m
        else:
            assert trace.wrap.plastic_strain_max > yield_strain
            peak_m = x_m.min()
            energy_j = tether_pull_n(layout, wrap, peak_m)[0] ** 2 / (2 * k_n_per_m)
            back_m = energy_j / ((0.08 - 0.04) * weight_n)
            assert -x_m[-1] >= -peak_m - back_m > 10 * 0.1 * weight_n / k_n_per_m
            assert evaluate(trace).permanent_max_m == pytest.approx(-x_m[-1], abs=1e-3)


def test_three_layer_example_fails_unwrapped_where_the_example_wraps_pass():
    """At 0.4 g its columns (0.99 m on a 0.19 m side, tipping statically from 0.19 g) topple
    unwrapped. (Not 0.3 g: a fresh unit sways 108 mm there, 9.5 % of its height against the
    10 % limit, a knife edge; the lab's unit, carried from 0.2 g, fails it.)"""
    load = LoadUnit.from_toml(EXAMPLE_3)
    assert not evaluate(run_level(load.layout(), PulseProfile(0.4))).passed
    for path in ("examples/wrap_kraft_3layer.toml", "examples/wrap_lldpe_3layer.toml"):
        wrap = WrapFormat.from_toml(path, load.load_height_m)
        verdict = evaluate(run_level(load.layout(), PulseProfile(0.4), wrap=wrap))
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
    assert np.array_equal(a.bundle_pos_m, b.bundle_pos_m) and a.wrap == b.wrap


# -- what limits a paper wrap on the bench (issue 12) ---------------------------------------


def kraft_card(**changes) -> dict:
    """The Kraft card as a custom [material] table, with changes."""
    card = dict(kind="paper", grammage_kg_m2=0.09, stiffness_n_per_m=4.0e5, yield_strain=0.008,
                break_strain=0.07, hardening_ratio=0.1125, cd_ratio=0.6, thickness_m=1.3e-4)
    return {**card, **changes}


def test_a_weak_seam_opens_and_fails_the_verdict():
    """One layer of Kraft at 250 N round one layer of bundles: the tail holds that layer's
    whole tension (no turn beneath it), 250 N / 0.5 m = 500 N/m at rest. A glued tail of
    3000 N/m holds it through a 0.5 g pulse; one of 700 N/m holds it at rest (0.71) but lets
    go when the bundles push out, and then every ring it closes goes slack."""
    verdicts = {}
    for seam in (3000.0, 700.0):
        wrap = wrap_format(kraft_card(seam_strength_n_per_m=seam), [(0.0, 0.474, 1, 250.0)])
        verdicts[seam] = evaluate(run_level(one_layer().layout(), PulseProfile(0.5), wrap=wrap))
    strong, weak = verdicts[3000.0], verdicts[700.0]
    assert not strong.wrap.opened and strong.criteria["no_damage"]
    assert weak.wrap.opened and WRAP_OPENED in weak.damage
    assert not weak.passed and not weak.criteria["no_damage"]
    seam = next(p for p in weak.wrap.places if p.element == "seam")
    assert seam.opened and seam.utilisation == 1.0 and seam.t_s > 0   # during the pulse
    assert weak.to_json()["wrap"]["opened"] is True
    assert weak.elastic_max_m > strong.elastic_max_m + 0.05


def test_once_the_seam_lets_go_its_rings_pull_nothing():
    """The same tail of 700 N/m without the bench, the web on the bundles alone: it holds
    the unit at rest, then the layer's bundles are pushed out 0.1 mm at a time until it lets
    go. From that step on the rings it closes (both) are slack: they press on no corner,
    however far the bundles are pushed (the face diagonals still pull)."""
    layout = one_layer().layout()
    wrap = wrap_format(kraft_card(seam_strength_n_per_m=700.0), [(0.144, 0.474, 1, 250.0)])
    net = WrapNet(wrap, layout)
    pos, rot = rest_state(layout)
    net.freeze(pos, rot)
    zero = np.zeros_like(pos)
    outward = np.zeros_like(pos)
    outward[1:, :2] = np.sign(pos[1:, :2])
    for step in range(50):
        force, _ = net.forces(pos + outward * 1e-4 * step, rot, zero, zero)
        if net.rings.opened.any():
            break
    assert net.rings.opened[net.seam].all() and step > 1
    assert np.all(net._push == 0.0)             # slack from the step it let go
    assert net.seam_peak == 1.0
    assert np.all(net.rings.last_n[net.seam] == 0.0)
    force, _ = net.forces(pos + outward * 5e-4 * step, rot, zero, zero)
    assert len(net.seam) == 2 and np.abs(force).max() > 0.0
    assert np.all(net.rings.last_n == 0.0) and np.all(net._push == 0.0)


@pytest.mark.slow
def test_more_paper_layers_at_the_same_tension_never_move_the_load_more():
    """Kraft at 250 N over the whole 3-layer example at 0.8 g, 1, 2 and 4 layers: never more
    elastic displacement (within the 2 mm noise), and 4 layers at least a quarter less than one
    (measured on the converged bench, 2026-11-24: 55.6, 43.2, 30.9 mm). Where the load is soft
    (its give halved) the web's stiffness does not decide, the layers' squeeze and friction do,
    and 4 layers still move it measurably less than 2."""
    load = LoadUnit.from_toml(EXAMPLE_3)
    h = load.load_height_m
    disp = [elastic_max(load, wrap_format("kraft", [(0.0, h, n, 250.0)]), 0.8) for n in (1, 2, 4)]
    assert all(b <= a + MONOTONE_TOLERANCE_M for a, b in zip(disp, disp[1:], strict=False)), disp
    assert disp[2] < 0.75 * disp[0], disp
    soft = load.with_give(0.5)
    two, four = (elastic_max(soft, wrap_format("kraft", [(0.0, h, n, 250.0)]), 0.8)
                 for n in (2, 4))
    assert four < two - 2 * MONOTONE_TOLERANCE_M, (two, four)


def test_the_3_layer_example_is_most_loaded_where_the_pallet_shears_the_load():
    """Hand argument. At 0.8 g the stopper holds the pallet and the load is thrown backwards.
    Friction holds what it can at each joint: 0.5 g under the first layer (pallet on shrink
    film), 0.4 g between layers. The wrap carries the rest, (0.8 - mu) g times the mass above
    the joint: 0.3 x 3 layers at the pallet, 0.4 x 2 and 0.4 x 1 at the joints above. So the
    pallet joint needs the most shear, and a box of membrane carries shear in the faces that
    run along the motion (+y and -y, as diagonal tension), not in those across it. The two
    most loaded places are therefore the -y and +y face diagonals between the pallet round
    and the first layer, above any ±x face there and any face diagonal higher up."""
    load = LoadUnit.from_toml(EXAMPLE_3)
    wrap = WrapFormat.from_toml("examples/wrap_kraft_3layer.toml", load.load_height_m)
    report = evaluate(run_level(load.layout(), PulseProfile(0.8), wrap=wrap)).wrap
    pallet_joint = (0.072 + 0.2265) / 2
    top_two = report.critical[:2]
    assert {p.where for p in top_two} == {"face -y", "face +y"}
    assert all(p.element == "diagonals" and p.height_m == pytest.approx(pallet_joint)
               for p in top_two)
    diagonals = [p for p in report.places if p.element == "diagonals"]
    across = max(p.utilisation for p in diagonals
                 if p.where in ("face +x", "face -x") and p.height_m == pytest.approx(pallet_joint))
    higher = max(p.utilisation for p in diagonals if p.height_m > pallet_joint + 0.01)
    assert min(p.utilisation for p in top_two) > max(across, higher)
    assert not report.torn and 0.1 < report.peak_utilisation < 1.0


@pytest.mark.parametrize("iterations, creeps", [(50, False), (20, True)])
def test_a_squeezed_stack_does_not_creep_below_its_friction(iterations, creeps):
    """Statics: at 0.2 and 0.3 g the sled pulls less than every static friction of the 3-layer
    example holds (0.5 g on the pallet, 0.4 g between layers), and the wrap keeps its columns
    from tipping, so nothing can slide: one unit through both levels ends where it stood. The
    machine's 800 N Kraft default squeezes each layer with kilonewtons; a solve converged for
    it (the wrapped default, 50 iterations) keeps it still, 20 iterations let it creep (measured
    2026-11-24: 0.7 and 1.8 mm at 0.2 and 0.3 g, against 24.6 mm at 0.2 g with 20 iterations;
    benchmarks/bench_solver.py). How far it creeps is the unconverged solve's path, not a
    property of the unit (9.0 mm since the world rounds the wrap's forces, 2026-11-26): the
    test asks for twice the still bound."""
    load = LoadUnit.from_toml(EXAMPLE_3)
    assert (load.friction.pallet_bundle.static, load.friction.bundle_bundle.static) == (0.5, 0.4)
    wrap = WrapFormat.from_toml("examples/program_kraft_default.toml", load.load_height_m)
    settings = SimSettings(solver_iterations=iterations,
                           max_solver_iterations=iterations)
    run = run_levels(load, [0.2, 0.3], settings, wrap=wrap)
    total = max(v.permanent_total_max_m for v in run.verdict.levels)
    if creeps:
        assert total > 0.006, total
    else:
        assert total < 0.003, total     # the bench's jitter at rest, not a slide


def _top_wraps(count: int, load_height_m: float) -> WrapFormat:
    text = Path("examples/program_kraft_default.toml").read_text()
    return WrapFormat.from_dict(
        tomllib.loads(re.sub(r"(?m)^top_wraps = \d+", f"top_wraps = {count}", text)),
        "ten top wraps", load_height_m)


@pytest.mark.parametrize("most, rests", [(200, True), (50, False)])
def test_more_wrap_does_not_let_the_stack_creep_more(most, rests):
    """Statics again, on the 2-layer example at 0.2 g: twenty top wraps at the Kraft default's
    800 N (it lays three) squeeze harder than 50 iterations converge; the stack creeps 15 mm
    and is still moving 3 s after the sled stopped, so more wrap looked worse than less (a
    user found it with ten, 2026-11-26, when the stop bar stood 1 mm behind the pallet: 6.9
    mm; flush, ten rest at 50). A run that creeps with nothing damaged is made again with
    twice the iterations: 100 hold it still (0.8 mm), as the default program is held."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    settings = SimSettings(max_solver_iterations=most)
    heard: list[int] = []
    run = run_levels(load, [0.2], settings, wrap=_top_wraps(20, load.load_height_m),
                     on_rerun=heard.append)
    level = run.verdict.levels[0]
    if rests:
        assert run.solver_iterations == 100 and not level.not_at_rest
        assert level.permanent_max_m < 0.002, level.permanent_max_m
        assert heard == [100]   # a progress bar starts again
        assert run.unsolved_at == ((50, "crept on under static friction"),)
    else:
        assert run.solver_iterations == 50 and level.not_at_rest
        assert heard == [] and run.unsolved_at == ()
        assert level.permanent_max_m > 0.004, level.permanent_max_m


def test_a_stack_that_creeps_at_every_count_is_run_up_to_the_most_iterations_and_judged_there(
        monkeypatch):
    """Each run that creeps is made again with twice the iterations while that stays within
    `max_solver_iterations` (200: 50, 100, then 200, the most included), and the last
    one's verdict is the answer, the counts it crept at said."""
    monkeypatch.setattr(bench, "unconverged", lambda run: "crept")
    load, wrap = kraft_example()
    heard: list[int] = []
    run = run_levels(load, [0.2], wrap=wrap, on_rerun=heard.append)
    assert heard == [100, 200] and run.unsolved_at == ((50, "crept"), (100, "crept"))
    assert run.solver_iterations == 200 and run.verdict.levels[0].passed


def test_a_squeeze_that_leaves_bodies_inside_each_other_is_solved_again_with_more_iterations():
    """Found in training's random episodes: one layer of fifteen light, tall bundles (4.3 kg)
    under six bottom wraps at Kraft's 800 N, three reinforcement wraps at 247 N and two top
    wraps at 594 N, laid 9 % tighter and 22 % stiffer than nominal (a verification sample), at
    training's 1/160 s step. Relaxed for 16 h the bottom wraps hold 774 N each, and six of them
    pull each corner bundle inward with 6 x 774 N x sqrt(2) = 6.6 kN, 156 x its weight: 50
    iterations leave bodies 23 mm inside each other for 0.1 s, a run that used to end invalid.
    Made again with 100 it is solved, and passes with the unit held within 1 cm."""
    load = LoadUnit(
        name="one layer of light, tall bundles",
        pallet=Pallet(length_m=1.2, width_m=0.8, height_m=0.144, mass_kg=25.0,
                      safe_load_kg=1500.0),
        bundle=Bundle(length_m=0.395, width_m=0.155, height_m=0.338, mass_kg=4.3,
                      corner_stiffness_n_per_m2=6e5, edge_radius_m=0.045),
        stack=Stack(layers=1, pattern="columnar", positions=()),
        friction=Friction(sled_pallet=FrictionPair(0.49, 0.42),
                          pallet_bundle=FrictionPair(0.29, 0.24),
                          bundle_bundle=FrictionPair(0.34, 0.25)),
        pallet_stopper=True)
    program = Program(bottom_wraps=6, bottom_from_m=0.032, bottom_tension_n=800.0,
                      up_overlap=0.15, middle_tension_n=80.0, top_wraps=2,
                      top_overhang_m=0.05, top_tension_n=594.0,
                      reinforcements=(Reinforcement(from_m=0.032, wraps=3, tension_n=247.0),))
    sample = Sample(friction={}, mass_scale=1.0, stiffness_scale=1.2162, tension_scale=1.0896,
                    relaxation_scale=0.98, hours_since_wrapping=16.0, give_scale=1.278)
    unit = sample.load(load)
    wrap = sample.wrap(WrapFormat.from_program(MATERIALS["kraft"], 0.5, program,
                                               load.load_height_m, "kraft"))
    retained = MATERIALS["kraft"].relaxation.retained(16.0)
    assert 800.0 * 1.0896 * (1 - (1 - retained) * 0.98) == pytest.approx(774, abs=0.5)
    training = SimSettings.training()
    once = run_levels(unit, [0.5], replace(training, max_solver_iterations=50),
                      orientation="short", wrap=wrap)
    assert not once.verdict.valid
    assert once.traces[0].unsolved == "left bodies inside each other"
    run = run_levels(unit, [0.5], training, orientation="short", wrap=wrap)
    assert run.unsolved_at == ((50, "left bodies inside each other"),)
    assert run.solver_iterations == 100 and run.verdict.valid and run.verdict.passed
    assert run.verdict.levels[0].elastic_max_m < 0.01


def test_a_wrapped_level_s_places_peak_at_times_of_the_run_the_most_loaded_in_the_pulse():
    """The report's times count from the pulse's start, as the trace's do: every place peaks
    within the run, and the 2-layer example's most loaded one (its Kraft rings' corners) while
    the sled holds 0.5 g (0.05 to 0.55 s), where the load leans on the wrap."""
    load, wrap = kraft_example()
    trace = run_level(load.layout(), PulseProfile(0.5), wrap=wrap)
    assert trace.wrap is not None
    times = [p.t_s for p in trace.wrap.places if p.t_s is not None]
    assert times and 0.0 <= min(times) and max(times) <= trace.t_s[-1]
    peak_t_s = trace.wrap.critical[0].t_s
    assert peak_t_s is not None and 0.05 <= peak_t_s <= 0.55


def test_the_wrap_is_laid_smoothly_over_the_first_two_thirds_of_the_settling(monkeypatch):
    """The wrapping tension comes on as a smoothstep 3x^2 - 2x^3 of the settling's first two
    thirds (x = step / (2/3 of the steps)): from nothing, half on at a third, all on from two
    thirds to the end, never falling back; switched on at once, a full squeeze slams light
    bundles into each other."""
    laid: list[float] = []
    real = WrapNet.laying

    def heard(self: WrapNet, fraction: float) -> None:
        laid.append(fraction)
        real(self, fraction)

    monkeypatch.setattr(WrapNet, "laying", heard)
    load, wrap = kraft_example()
    settings = SimSettings()
    run_level(load.layout(), PulseProfile(0.2), settings, wrap)
    n = round(settings.settle_s / settings.timestep_s)              # 72 steps
    x = np.minimum(np.arange(n) / (2 * n / 3), 1.0)
    assert laid == pytest.approx(list(3 * x**2 - 2 * x**3), abs=1e-12)
    assert laid[0] == 0.0 and laid[n // 3] == pytest.approx(0.5) and laid[2 * n // 3:] == \
        [1.0] * (n - 2 * n // 3)
    assert all(b >= a for a, b in zip(laid, laid[1:], strict=False))

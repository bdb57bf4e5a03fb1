"""Specification of LOAD.toml: presets, stacking patterns, bundle names, friction, bad input."""

from __future__ import annotations

import re
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from wrapenv.config import InputError
from wrapenv.load import (
    EUR_SAFE_LOAD_KG,
    MAX_SAFE_LOAD_KG,
    Bundle,
    Friction,
    FrictionPair,
    LoadUnit,
    Pallet,
)
from wrapenv.load_checks import (
    MAX_BUNDLES,
    MAX_LOAD_HEIGHT_M,
    MIN_BUNDLE_SIDE_M,
    _bundle_count,
    fit,
)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
NAME = re.compile(r"^L(\d+)C(\d+)R(\d+)$")


def minimal(**tables) -> dict:
    data = {
        "pallet": {"preset": "EUR"},
        "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 1},
    }
    data.update(tables)
    return data


@pytest.mark.parametrize("layers", [1, 2, 3, 4])
@pytest.mark.parametrize("example", ["pet_2layer_columnar", "pet_3layer_interlocked",
                                     "pet_3layer_half_pallet"])
def test_the_bundles_counted_before_laying_out_are_those_laid_out(example, layers):
    """The limits (the bench's most bundles, the pallet's safe load) are checked on a count
    made without placing the bundles: it must be the layout's, straight and turned layers
    alike."""
    unit = LoadUnit.from_toml(f"examples/{example}.toml")
    unit = replace(unit, stack=replace(unit.stack, layers=layers))
    assert _bundle_count(unit) == len(unit.layout().bundles)
    explicit = LoadUnit.from_dict(minimal(stack={"layers": layers, "pattern": "explicit",
                                                 "positions": [[-0.3, 0.0], [0.3, 0.0]]}))
    assert _bundle_count(explicit) == len(explicit.layout().bundles) == 2 * layers


def by_layer(layout) -> dict[int, list]:
    out: dict[int, list] = {}
    for b in layout.bundles:
        out.setdefault(b.layer, []).append(b)
    return out


def inside_pallet(layout, tol: float = 1e-3) -> bool:
    px, py, _ = layout.pallet_size_m
    return all(
        abs(b.centre_m[0]) + b.size_m[0] / 2 <= px / 2 + tol
        and abs(b.centre_m[1]) + b.size_m[1] / 2 <= py / 2 + tol
        for b in layout.bundles
    )


# --- presets -----------------------------------------------------------------------------------


def test_eur_pallet_preset_is_1200_by_800_by_144_mm_and_25_kg():
    unit = LoadUnit.from_dict(minimal())
    assert unit.pallet == Pallet(1.2, 0.8, 0.144, 25.0)


@pytest.mark.parametrize("preset, pallet", [
    ("EUR", Pallet(1.2, 0.8, 0.144, 25.0, 1500.0)),     # EPAL 1
    ("EPAL2", Pallet(1.2, 1.0, 0.162, 35.0, 1250.0)),   # with its base frame
    ("EPAL3", Pallet(1.0, 1.2, 0.144, 30.0, 1500.0)),
    ("EPAL6", Pallet(0.8, 0.6, 0.144, 9.5, 500.0)),     # the half pallet
])
def test_epal_presets_give_size_mass_and_safe_working_load(preset, pallet):
    assert LoadUnit.from_dict(minimal(pallet={"preset": preset})).pallet == pallet


def test_a_pallet_given_by_its_size_alone_carries_what_a_euro_pallet_carries():
    unit = LoadUnit.from_dict(minimal(
        pallet={"length_m": 1.0, "width_m": 1.0, "height_m": 0.15, "mass_kg": 20}))
    assert unit.pallet.safe_load_kg == EUR_SAFE_LOAD_KG == 1500.0


def test_safe_load_overrides_a_preset_s_and_is_written_out():
    unit = LoadUnit.from_dict(minimal(pallet={"preset": "EPAL6", "safe_load_kg": 600.0}))
    assert unit.pallet.safe_load_kg == 600.0
    assert LoadUnit.from_dict(unit.to_dict()) == unit
    assert tomllib.loads(unit.to_toml())["pallet"]["safe_load_kg"] == 600.0


def test_pet_bundle_preset_is_280_by_190_by_330_mm_and_9_3_kg():
    unit = LoadUnit.from_dict(minimal())
    assert unit.bundle == Bundle(0.28, 0.19, 0.33, 9.3)


def test_keys_next_to_a_preset_override_only_those_values():
    unit = LoadUnit.from_dict(minimal(
        pallet={"preset": "EUR", "mass_kg": 30.0},
        bundle={"preset": "PET6x1.5L", "height_m": 0.30},
    ))
    assert unit.pallet == Pallet(1.2, 0.8, 0.144, 30.0)
    assert unit.bundle == Bundle(0.28, 0.19, 0.30, 9.3)


def test_dimensions_without_a_preset_are_taken_as_given():
    unit = LoadUnit.from_dict(minimal(
        pallet={"length_m": 1.0, "width_m": 1.0, "height_m": 0.15, "mass_kg": 20},
        bundle={"length_m": 0.3, "width_m": 0.2, "height_m": 0.25, "mass_kg": 5},
    ))
    assert unit.pallet == Pallet(1.0, 1.0, 0.15, 20.0)
    assert unit.bundle == Bundle(0.3, 0.2, 0.25, 5.0)


# --- the load's give: how the bundles' vertical edges take the wrap ------------------------


def test_the_pet_preset_s_give_is_its_documented_corner_stiffness_and_bottle_radius():
    bundle = LoadUnit.from_dict(minimal()).bundle
    assert bundle.corner_stiffness_n_per_m2 == 6.0e5     # docs/materials.md, section 5, B1
    assert bundle.edge_radius_m == 0.045                  # a 1.5 L bottle's ~90 mm diameter


def test_a_bundle_without_give_keys_gets_the_documented_defaults():
    unit = LoadUnit.from_dict(minimal(
        bundle={"length_m": 0.4, "width_m": 0.3, "height_m": 0.3, "mass_kg": 8.0}))
    assert unit.bundle.corner_stiffness_n_per_m2 == 6.0e5 and unit.bundle.edge_radius_m == 0.045
    small = LoadUnit.from_dict(minimal(
        bundle={"length_m": 0.06, "width_m": 0.05, "height_m": 0.2, "mass_kg": 0.5}))
    assert small.bundle.edge_radius_m == 0.025   # no rounder than half its smaller side


def test_a_carton_s_give_is_taken_as_given_and_reaches_every_placed_bundle():
    unit = LoadUnit.from_dict(minimal(bundle={"preset": "PET6x1.5L", "edge_radius_m": 0.003,
                                              "corner_stiffness_n_per_m2": 2.0e6}))
    assert {(b.corner_stiffness_n_per_m2, b.edge_radius_m)
            for b in unit.layout().bundles} == {(2.0e6, 0.003)}


def test_with_give_scales_the_corner_stiffness_only():
    unit = LoadUnit.from_dict(minimal())
    soft = unit.with_give(0.5)
    assert soft.bundle.corner_stiffness_n_per_m2 == 3.0e5
    assert replace(soft.bundle, corner_stiffness_n_per_m2=6.0e5) == unit.bundle
    assert unit.bundle.corner_stiffness_n_per_m2 == 6.0e5   # the original is untouched


def test_a_load_with_its_give_reads_back_equal():
    unit = LoadUnit.from_dict(minimal(bundle={"preset": "PET6x1.5L", "edge_radius_m": 0.003}))
    assert LoadUnit.from_dict(tomllib.loads(unit.to_toml())) == unit


# --- columnar pattern and names ------------------------------------------------------------


@pytest.fixture(scope="module")
def columnar2() -> LoadUnit:
    return LoadUnit.from_toml(EXAMPLES / "pet_2layer_columnar.toml")


def test_columnar_eur_pet_layer_holds_16_bundles(columnar2):
    layers = by_layer(columnar2.layout())
    assert sorted(layers) == [1, 2]
    assert [len(layers[k]) for k in (1, 2)] == [16, 16]


def test_bundles_are_named_by_layer_column_and_row(columnar2):
    names = [b.name for b in columnar2.layout().bundles]
    expected = {f"L{layer}C{c}R{r}" for layer in (1, 2) for c in range(1, 5) for r in range(1, 5)}
    assert len(names) == len(set(names))
    assert set(names) == expected


def test_column_counts_along_x_and_row_along_y_from_the_smallest(columnar2):
    for b in columnar2.layout().bundles:
        layer, col, row = (int(g) for g in NAME.match(b.name).groups())
        assert layer == b.layer
    for bundles in by_layer(columnar2.layout()).values():
        for a in bundles:
            ca, ra = (int(g) for g in NAME.match(a.name).groups()[1:])
            for b in bundles:
                cb, rb = (int(g) for g in NAME.match(b.name).groups()[1:])
                if ca < cb:
                    assert a.centre_m[0] < b.centre_m[0] - 0.1, (a.name, b.name)
                if ca == cb:
                    assert a.centre_m[0] == pytest.approx(b.centre_m[0])
                if ra < rb:
                    assert a.centre_m[1] < b.centre_m[1] - 0.1, (a.name, b.name)
                if ra == rb:
                    assert a.centre_m[1] == pytest.approx(b.centre_m[1])


def test_c1r1_is_the_bundle_at_smallest_x_and_smallest_y(columnar2):
    first = [b for b in columnar2.layout().bundles if b.layer == 1]
    c1r1 = next(b for b in first if b.name == "L1C1R1")
    assert c1r1.centre_m[0] == min(b.centre_m[0] for b in first)
    assert c1r1.centre_m[1] == min(b.centre_m[1] for b in first)


def test_columnar_layers_stand_exactly_on_top_of_each_other(columnar2):
    layers = by_layer(columnar2.layout())
    lower = {b.name[2:]: b for b in layers[1]}
    for b in layers[2]:
        below = lower[b.name[2:]]
        assert b.centre_m[:2] == pytest.approx(below.centre_m[:2])
        assert b.centre_m[2] == pytest.approx(below.centre_m[2] + 0.33)


def test_columnar_bundles_stay_on_the_pallet(columnar2):
    assert inside_pallet(columnar2.layout())


@pytest.mark.parametrize("example, layers", [
    ("pet_2layer_columnar.toml", 2),
    ("pet_3layer_columnar.toml", 3),
])
def test_load_height_is_pallet_plus_every_layer(example, layers):
    unit = LoadUnit.from_toml(EXAMPLES / example)
    expected = 0.144 + layers * 0.33
    assert unit.load_height_m == pytest.approx(expected)
    assert unit.layout().load_height_m == pytest.approx(expected)


def test_bundles_rest_on_the_pallet_top_at_z_of_pallet_height(columnar2):
    for b in columnar2.layout().bundles:
        bottom = b.centre_m[2] - b.size_m[2] / 2
        assert bottom == pytest.approx(0.144 + (b.layer - 1) * 0.33)


def test_mass_is_pallet_plus_every_bundle(columnar2):
    assert columnar2.mass_kg == pytest.approx(25.0 + 32 * 9.3)


# --- interlocked and explicit patterns -------------------------------------------------------


def test_interlocked_turns_every_second_layer_90_degrees():
    unit = LoadUnit.from_toml(EXAMPLES / "pet_3layer_interlocked.toml")
    layers = by_layer(unit.layout())
    assert sorted(layers) == [1, 2, 3]
    for layer, bundles in layers.items():
        sizes = {b.size_m for b in bundles}
        turned = (0.18, 0.36, 0.33)
        straight = (0.36, 0.18, 0.33)
        assert sizes == ({turned} if layer == 2 else {straight}), layer
    assert [len(layers[k]) for k in (1, 2, 3)] == [12, 12, 12]
    assert inside_pallet(unit.layout())


def test_interlocked_turned_layer_bridges_the_joints_below():
    layout = LoadUnit.from_toml(EXAMPLES / "pet_3layer_interlocked.toml").layout()
    supports = layout.supports()
    for b, below in zip(layout.bundles, supports, strict=True):
        if b.layer == 2:
            assert len(below) >= 2, f"{b.name} rests on {len(below)} bundle(s) only"


def test_a_fourth_interlocked_layer_lies_as_the_second():
    interlocked = LoadUnit.from_toml(EXAMPLES / "pet_3layer_interlocked.toml")
    layers = by_layer(replace(interlocked, stack=replace(interlocked.stack, layers=4)).layout())
    sizes = {layer: {b.size_m for b in bundles} for layer, bundles in layers.items()}
    assert sizes[1] == sizes[3] != sizes[2] == sizes[4]


def test_a_bundle_rests_on_the_bundles_of_the_layer_below_under_it():
    """Three columns of three layers, two side by side and one off to the side: each bundle
    above the first layer rests on the one beneath it alone, none on a bundle two layers down
    or beside it."""
    layout = LoadUnit.from_dict(minimal(stack={
        "layers": 3, "pattern": "explicit",
        "positions": [[-0.3, 0.0], [0.0, 0.0], [0.3, 0.2]]})).layout()
    names = [b.name for b in layout.bundles]
    resting = {names[k]: sorted(names[j] for j in below)
               for k, below in enumerate(layout.supports())}
    for b in layout.bundles:
        beneath = [o.name for o in layout.bundles if o.layer == b.layer - 1
                   and o.centre_m[:2] == b.centre_m[:2]]
        assert resting[b.name] == beneath, b.name
    assert sum(map(len, resting.values())) == 6      # layers 2 and 3, one each


def test_the_outline_is_the_bundles_extent_seen_from_above():
    """0.28 x 0.19 m bundles centred at x = -0.3 and 0.1, y = 0.0 and 0.2: from x = -0.44 to
    0.24 and from y = -0.095 to 0.295, wherever they stand on the pallet."""
    layout = LoadUnit.from_dict(minimal(stack={
        "layers": 1, "pattern": "explicit", "positions": [[-0.3, 0.0], [0.1, 0.2]]})).layout()
    assert layout.outline_m == pytest.approx((0.68, 0.39))


def test_explicit_positions_are_used_on_every_layer():
    unit = LoadUnit.from_dict(minimal(
        stack={"layers": 3, "pattern": "explicit", "positions": [[-0.3, 0.0], [0.3, 0.1]]},
    ))
    layers = by_layer(unit.layout())
    assert sorted(layers) == [1, 2, 3]
    for layer, bundles in layers.items():
        assert sorted(b.centre_m[:2] for b in bundles) == [(-0.3, 0.0), (0.3, 0.1)]
        assert {b.size_m for b in bundles} == {(0.28, 0.19, 0.33)}
        assert {b.name for b in bundles} == {f"L{layer}C1R1", f"L{layer}C2R2"}


def test_explicit_integer_positions_are_accepted():
    unit = LoadUnit.from_dict(minimal(stack={"layers": 1, "pattern": "explicit",
                                             "positions": [[0, 0]]}))
    assert unit.layout().bundles[0].centre_m[:2] == (0.0, 0.0)


# --- orientation -------------------------------------------------------------------------------


def test_short_orientation_turns_the_pallet_and_keeps_the_bundle_count(columnar2):
    long, short = columnar2.layout(), columnar2.layout("short")
    assert long.pallet_size_m == pytest.approx((1.2, 0.8, 0.144))
    assert short.pallet_size_m == pytest.approx((0.8, 1.2, 0.144))
    assert len(short.bundles) == len(long.bundles) == 32
    assert {b.size_m for b in short.bundles} == {(0.19, 0.28, 0.33)}
    assert inside_pallet(short)
    assert short.load_height_m == pytest.approx(long.load_height_m)


def test_short_orientation_renames_columns_along_the_new_x(columnar2):
    short = columnar2.layout("short")
    names = {b.name for b in short.bundles}
    assert len(names) == 32
    first = [b for b in short.bundles if b.layer == 1]
    c1r1 = next(b for b in first if b.name == "L1C1R1")
    assert c1r1.centre_m[0] == min(b.centre_m[0] for b in first)
    assert c1r1.centre_m[1] == min(b.centre_m[1] for b in first)


def test_long_orientation_of_a_long_pallet_is_the_file_layout(columnar2):
    assert columnar2.layout("long") == columnar2.layout()


# --- friction ------------------------------------------------------------------------------


def test_friction_defaults_when_the_table_is_absent():
    unit = LoadUnit.from_dict(minimal())
    assert unit.friction == Friction()
    assert unit.friction.sled_pallet == FrictionPair(0.45, 0.34)
    assert unit.friction.pallet_bundle == FrictionPair(0.30, 0.23)
    assert unit.friction.bundle_bundle == FrictionPair(0.30, 0.23)
    for name in ("sled_pallet", "pallet_bundle", "bundle_bundle"):
        pair = unit.friction.pair(name)
        assert pair.kinetic <= pair.static


def test_friction_pairs_are_read_per_pair_and_the_rest_keep_defaults():
    unit = LoadUnit.from_dict(minimal(friction={
        "pallet_bundle": {"static": 0.5, "kinetic": 0.42},
    }))
    assert unit.friction.pallet_bundle == FrictionPair(0.5, 0.42)
    assert unit.friction.sled_pallet == Friction().sled_pallet
    assert unit.friction.bundle_bundle == Friction().bundle_bundle


def test_example_friction_matches_contracts(columnar2):
    assert columnar2.friction == Friction(
        FrictionPair(0.45, 0.40), FrictionPair(0.50, 0.42), FrictionPair(0.40, 0.33))


def test_kinetic_equal_to_static_is_accepted():
    unit = LoadUnit.from_dict(minimal(friction={"sled_pallet": {"static": 0.4, "kinetic": 0.4}}))
    assert unit.friction.sled_pallet == FrictionPair(0.4, 0.4)


def test_pallet_stopper_defaults_to_false_and_can_be_set():
    assert LoadUnit.from_dict(minimal()).pallet_stopper is False
    unit = LoadUnit.from_dict(minimal(fixture={"pallet_stopper": True}))
    assert unit.pallet_stopper is True
    assert unit.layout().pallet_stopper is True


# --- bad input: one line naming the file and the field -----------------------------------------

BAD_LOADS = {
    # id: (changes to BASE_LOAD, expected dotted field)
    "missing bundle table": ({"bundle": None}, "bundle"),
    "missing pallet table": ({"pallet": None}, "pallet"),
    "missing stack table": ({"stack": None}, "stack"),
    "missing mass": ({"bundle.mass_kg": None}, "bundle.mass_kg"),
    "missing length": ({"bundle.length_m": None}, "bundle.length_m"),
    "zero mass": ({"bundle.mass_kg": 0}, "bundle.mass_kg"),
    "negative mass": ({"bundle.mass_kg": -9.3}, "bundle.mass_kg"),
    "nan mass": ({"bundle.mass_kg": float("nan")}, "bundle.mass_kg"),
    "inf height": ({"bundle.height_m": float("inf")}, "bundle.height_m"),
    "string mass": ({"bundle.mass_kg": "9.3"}, "bundle.mass_kg"),
    "boolean width": ({"bundle.width_m": True}, "bundle.width_m"),
    "zero pallet height": ({"pallet.height_m": 0.0}, "pallet.height_m"),
    "negative pallet width": ({"pallet.width_m": -0.8}, "pallet.width_m"),
    "nan pallet mass": ({"pallet.mass_kg": float("nan")}, "pallet.mass_kg"),
    "unknown pallet preset": ({"pallet.preset": "US"}, "pallet.preset"),
    "zero safe load": ({"pallet.safe_load_kg": 0.0}, "pallet.safe_load_kg"),
    "nan safe load": ({"pallet.safe_load_kg": float("nan")}, "pallet.safe_load_kg"),
    "safe load no pallet bears": ({"pallet.safe_load_kg": MAX_SAFE_LOAD_KG + 1},
                                  "pallet.safe_load_kg"),
    "safe load a string": ({"pallet.safe_load_kg": "1500"}, "pallet.safe_load_kg"),
    "unknown bundle preset": ({"bundle.preset": "PET6x2L"}, "bundle.preset"),
    "unknown pattern": ({"stack.pattern": "pinwheel"}, "stack.pattern"),
    "zero layers": ({"stack.layers": 0}, "stack.layers"),
    "negative layers": ({"stack.layers": -1}, "stack.layers"),
    "fractional layers": ({"stack.layers": 2.5}, "stack.layers"),
    "word layers": ({"stack.layers": "two"}, "stack.layers"),
    "missing layers": ({"stack.layers": None}, "stack.layers"),
    "kinetic above static": (
        {"friction.pallet_bundle": {"static": 0.3, "kinetic": 0.4}},
        "friction.pallet_bundle.kinetic"),
    "zero static friction": (
        {"friction.sled_pallet": {"static": 0.0, "kinetic": 0.0}}, "friction.sled_pallet.static"),
    "nan kinetic friction": (
        {"friction.bundle_bundle": {"static": 0.3, "kinetic": float("nan")}},
        "friction.bundle_bundle.kinetic"),
    "missing kinetic friction": (
        {"friction.bundle_bundle": {"static": 0.3}}, "friction.bundle_bundle.kinetic"),
    "friction pair not a table": ({"friction.sled_pallet": 0.4}, "friction.sled_pallet"),
    "unknown friction pair": (
        {"friction.sled_bundle": {"static": 0.4, "kinetic": 0.3}}, "friction.sled_bundle"),
    "typo in friction pair key": (
        {"friction.sled_pallet": {"static": 0.4, "kinetic": 0.3, "dynamic": 0.3}},
        "friction.sled_pallet.dynamic"),
    "typo mass_kgs": ({"bundle.mass_kgs": 9.3}, "bundle.mass_kgs"),
    "typo in pallet": ({"pallet.lenght_m": 1.2}, "pallet.lenght_m"),
    "typo in stack": ({"stack.layer": 2}, "stack.layer"),
    "typo in fixture": ({"fixture.pallet_stoper": True}, "fixture.pallet_stoper"),
    "unknown top-level key": ({"wrap": "kraft"}, "wrap"),
    "stopper not a boolean": ({"fixture.pallet_stopper": "yes"}, "fixture.pallet_stopper"),
    "name not a string": ({"name": 42}, "name"),
    "explicit without positions": ({"stack.pattern": "explicit"}, "stack.positions"),
    "explicit with no position": (
        {"stack.pattern": "explicit", "stack.positions": []}, "stack.positions"),
    "explicit position of one number": (
        {"stack.pattern": "explicit", "stack.positions": [[0.0, 0.0], [0.3]]},
        "stack.positions[1]"),
    "explicit position not numbers": (
        {"stack.pattern": "explicit", "stack.positions": [["a", "b"]]}, "stack.positions[0]"),
    "explicit position nan": (
        {"stack.pattern": "explicit", "stack.positions": [[float("nan"), 0.0]]},
        "stack.positions[0]"),
    "explicit bundle overhangs": (
        {"stack.pattern": "explicit", "stack.positions": [[0.0, 0.0], [0.55, 0.0]]},
        "stack.positions"),
    "explicit bundle overhangs sideways": (
        {"stack.pattern": "explicit", "stack.positions": [[0.0, -0.35]]}, "stack.positions"),
    "explicit bundle bigger than the pallet": (
        {"stack.pattern": "explicit", "stack.positions": [[0.0, 0.0]], "bundle.length_m": 1.5},
        "stack.positions"),
    "explicit positions overlap": (
        {"stack.pattern": "explicit", "stack.positions": [[0.0, 0.0], [0.1, 0.05]]},
        "stack.positions"),
    "explicit duplicate positions": (
        {"stack.pattern": "explicit", "stack.positions": [[0.2, 0.1], [0.2, 0.1]]},
        "stack.positions[1]"),
    "bundle bigger than the pallet": ({"bundle.length_m": 1.5}, "bundle"),
    "give softer than a pillow": ({"bundle.corner_stiffness_n_per_m2": 1e3},
                                  "bundle.corner_stiffness_n_per_m2"),
    "give stiffer than the bench can couple": ({"bundle.corner_stiffness_n_per_m2": 1e8},
                                               "bundle.corner_stiffness_n_per_m2"),
    "give not a number": ({"bundle.corner_stiffness_n_per_m2": "stiff"},
                          "bundle.corner_stiffness_n_per_m2"),
    "zero edge radius": ({"bundle.edge_radius_m": 0.0}, "bundle.edge_radius_m"),
    "edge rounder than the bundle": ({"bundle.edge_radius_m": 0.1}, "bundle.edge_radius_m"),
    "nan edge radius": ({"bundle.edge_radius_m": float("nan")}, "bundle.edge_radius_m"),
    "typo in the give": ({"bundle.corner_stifness_n_per_m2": 6e5},
                         "bundle.corner_stifness_n_per_m2"),
    # impossible units (issue 17): no pallet carries them, or no bench could simulate them
    "a 1e-9 m bundle": ({"bundle.height_m": 1e-9}, "bundle.height_m"),
    "1 mm bundles": ({"bundle.length_m": 0.001, "bundle.width_m": 0.001}, "bundle.length_m"),
    "2 cm bundles": ({"bundle.width_m": 0.02}, "bundle.width_m"),
    "a million layers": ({"stack.layers": 1_000_000}, "stack.layers"),
    "200 layers, 66 m": ({"stack.layers": 200}, "stack.layers"),
    # the field to change: the layers, unless one layer alone is too tall
    "two layers of 1.45 m, 3.04 m": ({"stack.layers": 2, "bundle.height_m": 1.45},
                                     "stack.layers"),
    "one layer of 2.9 m, 3.04 m": ({"stack.layers": 1, "bundle.height_m": 2.9},
                                   "bundle.height_m"),
    "more bundles than the bench simulates": (
        {"bundle.length_m": 0.05, "bundle.width_m": 0.05, "bundle.height_m": 0.05,
         "bundle.mass_kg": 0.1}, "stack.layers"),
    "heavier than a pallet carries": ({"bundle.mass_kg": 50.0}, "bundle.mass_kg"),
    "a 1 g bundle of 17.6 L (0.06 kg/m³)": ({"bundle.mass_kg": 0.001}, "bundle.mass_kg"),
    # An interlocked stack whose turned layer has its outer bundles' centres beyond the
    # outermost columns below: pallet 1.2 m, straight columns of 0.5 m reach x = 0.501 m,
    # turned bundles 0.1 m wide are centred up to x = 0.51 m.
    "upper bundle centred over nothing": (
        {"stack.pattern": "interlocked", "bundle.length_m": 0.5, "bundle.width_m": 0.1,
         "bundle.height_m": 0.2, "bundle.mass_kg": 1.0},
        "stack.pattern"),
}


@pytest.mark.parametrize("changes, field", BAD_LOADS.values(), ids=BAD_LOADS.keys())
def test_bad_load_is_rejected_with_one_line_naming_file_and_field(
        changes, field, load_file, assert_input_error):
    path = load_file(changes)
    with pytest.raises(InputError) as info:
        LoadUnit.from_toml(path)
    assert_input_error(info.value, str(path), field)


def test_overlap_message_names_both_bundles(load_file):
    path = load_file({"stack.pattern": "explicit", "stack.positions": [[0.0, 0.0], [0.1, 0.0]]})
    with pytest.raises(InputError, match=r"L1C1R1.*L1C2R1.*overlap"):
        LoadUnit.from_toml(path)


def test_a_bundle_over_nothing_is_named_with_the_layer_below(load_file):
    path = load_file({"stack.pattern": "interlocked", "bundle.length_m": 0.5,
                      "bundle.width_m": 0.1, "bundle.height_m": 0.2, "bundle.mass_kg": 1.0})
    with pytest.raises(InputError, match=r"bundle L2C\d+R\d+ has its centre over no bundle of "
                                         r"layer 1 and would fall"):
        LoadUnit.from_toml(path)


def test_as_many_bundles_fit_as_their_2_mm_gaps_allow_the_last_flush_with_the_edge():
    # 4 x 0.298 m + 3 x 2 mm = 1.198 m: four, the fourth at the edge; 4 x 0.3 + 6 mm > 1.2 m
    assert (fit(1.198, 0.298), fit(1.197, 0.298), fit(1.2, 0.3)) == (4, 3, 3)


def test_overhang_message_names_the_bundle_and_amount(load_file):
    path = load_file({"stack.pattern": "explicit", "stack.positions": [[0.55, 0.0]]})
    with pytest.raises(InputError, match=r"L1C1R1 overhangs the pallet by 90 mm"):
        LoadUnit.from_toml(path)


def test_bundles_touching_side_by_side_do_not_overlap(load_file):
    path = load_file({"stack.pattern": "explicit", "stack.positions": [[-0.14, 0.0], [0.14, 0.0]]})
    assert len(LoadUnit.from_toml(path).layout().bundles) == 4


def test_bundle_flush_with_the_pallet_edge_does_not_overhang(load_file):
    path = load_file({"stack.pattern": "explicit", "stack.positions": [[0.6 - 0.14, 0.4 - 0.095]]})
    assert len(LoadUnit.from_toml(path).layout().bundles) == 2


def test_malformed_toml_is_rejected_naming_the_file(load_file, assert_input_error):
    path = load_file(text='name = "unterminated\n[bundle\nmass_kg = 9.3\n')
    with pytest.raises(InputError, match="malformed TOML") as info:
        LoadUnit.from_toml(path)
    assert_input_error(info.value, str(path), "")


def test_missing_load_file_is_rejected_naming_the_file(tmp_path, assert_input_error):
    path = tmp_path / "nowhere.toml"
    with pytest.raises(InputError, match="cannot read") as info:
        LoadUnit.from_toml(path)
    assert_input_error(info.value, str(path), "")


def test_a_folder_given_as_load_file_is_rejected(tmp_path, assert_input_error):
    with pytest.raises(InputError) as info:
        LoadUnit.from_toml(tmp_path)
    assert_input_error(info.value, str(tmp_path), "")


def test_load_file_that_is_not_utf8_is_rejected_naming_the_file(load_file, assert_input_error):
    path = load_file(text=b'name = "\xff\xfe caf\xe9"\n')
    with pytest.raises(InputError) as info:
        LoadUnit.from_toml(path)
    assert_input_error(info.value, str(path), "")


def test_interlocked_stack_whose_turned_layer_fits_no_bundle_is_rejected(load_file):
    # A 0.9 m long bundle fits lengthwise on an EUR pallet (1.2 m) but not turned across (0.8 m).
    path = load_file({"stack.pattern": "interlocked", "bundle.length_m": 0.9,
                      "bundle.width_m": 0.3, "bundle.height_m": 0.2})
    with pytest.raises(InputError):
        LoadUnit.from_toml(path)


def test_from_dict_names_its_source_in_errors(assert_input_error):
    with pytest.raises(InputError) as info:
        LoadUnit.from_dict(minimal(bundle={"preset": "PET6x1.5L", "mass_kgs": 1}),
                           source="inline")
    assert_input_error(info.value, "inline", "bundle.mass_kgs")


@pytest.mark.parametrize("name", ["PET 6×1.5 L \"bundles\"", "del\x7f and escape \x1b[31m",
                                  "tab\tand back\\slash"])
def test_to_toml_reads_back_equal_whatever_the_name(name):
    unit = replace(LoadUnit.from_toml(EXAMPLES / "pet_3layer_interlocked.toml"), name=name)
    assert LoadUnit.from_dict(tomllib.loads(unit.to_toml())) == unit


# --- unit slips: a figure in the wrong unit is refused, and the unit named -------------------

@pytest.mark.parametrize("edits, field, says", [
    ({"bundle.height_m": 330.0}, "bundle.height_m", "millimetres? height_m is in metres"),
    ({"pallet.length_m": 1200.0}, "pallet.length_m", "millimetres? length_m is in metres"),
    ({"bundle.mass_kg": 9300.0}, "bundle.mass_kg", "grams? mass_kg is in kilograms"),
    ({"friction.sled_pallet.static": 45.0}, "friction.sled_pallet.static",
     "a coefficient (the tangent of the slide angle: 0.45 for 24°), not a percentage"),
])
def test_a_figure_in_the_wrong_unit_is_named_as_such(load_file, edits, field, says,
                                                     assert_input_error):
    with pytest.raises(InputError) as err:
        LoadUnit.from_toml(path := load_file(edits))
    assert_input_error(err.value, str(path), field)
    assert says in err.value.message, err.value.message


@pytest.mark.parametrize("text, field", [
    ("sled_pallet = 0.45", "friction.sled_pallet"),
    ("sled_pallet = { static = 0.45 }", "friction.sled_pallet.kinetic"),
])
def test_a_pair_given_only_its_static_coefficient_is_told_the_ctu_code_s_kinetic_one(
        load_file, text, field, assert_input_error):
    """The CTU Code's tables give one coefficient; it advises kinetic = 0.75 x static, which the
    error works out (0.75 x 0.45 = 0.3375) rather than assume it silently."""
    base = (EXAMPLES / "pet_2layer_columnar.toml").read_text()
    line = "sled_pallet   = { static = 0.45, kinetic = 0.40 }"
    assert line in base
    path = load_file(text=base.replace(line, text))
    with pytest.raises(InputError) as err:
        LoadUnit.from_toml(path)
    assert_input_error(err.value, str(path), field)
    assert err.value.message.endswith("kinetic = 0.75 x static: kinetic = 0.34)")


def test_a_figure_too_large_in_any_unit_gets_no_guess(load_file):
    """5000 m is 5 m in millimetres, still no bundle: the error gives only the limit."""
    with pytest.raises(InputError) as err:
        LoadUnit.from_toml(load_file({"bundle.height_m": 5000.0}))
    assert err.value.message == "must be <= 3.0 (got 5000.0)"


# --- impossible units: the limits of docs/materials.md, section 6 -----------------------------

def test_a_unit_too_tall_for_a_trailer_names_the_limit_and_its_source(load_file):
    # 0.144 m pallet + 9 x 0.33 m = 3.114 m
    with pytest.raises(InputError, match=r"9 layers make the unit 3\.11 m tall, above the 3\.0 m"
                                         r" a road trailer takes inside \(European trailers"):
        LoadUnit.from_toml(load_file({"stack.layers": 9}))


@pytest.mark.parametrize("edits, field", [
    ({"stack.layers": 1, "pallet.height_m": 2.95}, "pallet.height_m"),
    ({"stack.layers": 1, "bundle.height_m": 2.9}, "bundle.height_m"),
])
def test_one_layer_too_tall_names_the_height_to_change_not_the_layers(load_file, edits,
                                                                       field):
    with pytest.raises(InputError) as err:
        LoadUnit.from_toml(load_file(edits))
    assert err.value.field == field


def test_a_unit_heavier_than_a_pallet_carries_names_the_limit_and_its_source(load_file):
    # 2 layers of 16 bundles: 32 x 47 kg = 1504 kg
    with pytest.raises(InputError, match=r"32 bundles of 47\.0 kg weigh 1504 kg, above the 1500 kg"
                                         r" the pallet carries \(its safe working load") as err:
        LoadUnit.from_toml(load_file({"bundle.mass_kg": 47.0}))
    assert err.value.field == "bundle.mass_kg"


def test_a_half_pallet_refuses_what_a_euro_pallet_carries():
    """Two layers of the PET bundles on EPAL's half pallet: 2 x 2 x 3 = 12 bundles; 12 x 45 kg
    = 540 kg is within the Euro pallet's 1500 kg but above the half pallet's 500 kg."""
    data = minimal(pallet={"preset": "EPAL6"}, stack={"layers": 2},
                   bundle={"preset": "PET6x1.5L", "mass_kg": 45.0})
    with pytest.raises(InputError, match=r"12 bundles of 45\.0 kg weigh 540 kg, above the 500 kg"):
        LoadUnit.from_dict(data)
    data["pallet"]["safe_load_kg"] = 540.0
    assert LoadUnit.from_dict(data).pallet.safe_load_kg == 540.0


def test_the_limits_themselves_are_allowed(load_file):
    """<= each limit passes: exactly 1500 kg of bundles, exactly 3.0 m tall, 5 cm bundles."""
    heaviest = LoadUnit.from_toml(load_file({"bundle.mass_kg": 1500 / 32}))
    assert len(heaviest.layout().bundles) * heaviest.bundle.mass_kg == pytest.approx(
        heaviest.pallet.safe_load_kg)
    tallest = LoadUnit.from_toml(load_file({
        "pallet": {"length_m": 1.2, "width_m": 0.8, "height_m": 0.5, "mass_kg": 25.0},
        "bundle.height_m": 0.25, "bundle.mass_kg": 1.0, "stack.layers": 10}))
    assert tallest.load_height_m == MAX_LOAD_HEIGHT_M
    smallest = LoadUnit.from_toml(load_file({
        "bundle.length_m": MIN_BUNDLE_SIDE_M, "bundle.width_m": MIN_BUNDLE_SIDE_M,
        "bundle.height_m": MIN_BUNDLE_SIDE_M, "bundle.mass_kg": 0.1, "stack.layers": 1}))
    assert len(smallest.layout().bundles) == 23 * 15 <= MAX_BUNDLES


def test_the_bundle_count_is_checked_before_any_bundle_is_placed(load_file, monkeypatch):
    """A million layers are refused from arithmetic alone: no layout is built."""
    def no_layout(*_args, **_kwargs):
        raise AssertionError("laid out")
    monkeypatch.setattr(LoadUnit, "layout", no_layout)
    path = load_file({"bundle.length_m": 0.05, "bundle.width_m": 0.05, "bundle.height_m": 0.05,
                      "bundle.mass_kg": 0.01, "stack.layers": 50})
    with pytest.raises(InputError, match=r"holds 17250 bundles, more than the 500"):
        LoadUnit.from_toml(path)

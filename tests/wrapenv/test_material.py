"""Material cards' failure fields (docs/materials.md, sections 1, 2 and 5): web thickness, how
stacked layers hold each other, the tail seam's strength; documented defaults for a custom
card that does not give them, one-line errors for values out of range."""

from __future__ import annotations

from typing import Any

import pytest

from wrapenv.config import InputError
from wrapenv.material import (
    DENSITY_KG_M3,
    FILM_RELAXATION,
    GLUED_SEAM_FRACTION,
    LOOKS,
    MATERIAL_KINDS,
    MATERIALS,
    NO_RELAXATION,
    PAPER_INTERLAYER_FRICTION,
    PAPER_RELAXATION,
)
from wrapenv.wrap import WrapFormat

#: The required values of a custom [material] table (a light film), tensions that it bears.
CUSTOM: dict[str, Any] = {"grammage_kg_m2": 0.012, "stiffness_n_per_m": 3000.0,
                          "yield_strain": 0.1, "break_strain": 0.5}
LOW_TENSION = {"band.0.tension_n": 100.0, "band.1.tension_n": 100.0}
#: The same as a paper: paper breaks before 30 % (`MAX_PAPER_BREAK_STRAIN`).
CUSTOM_PAPER: dict[str, Any] = {**CUSTOM, "kind": "paper", "break_strain": 0.2}


def test_kraft_is_paper_130_um_thick_sliding_at_0_4_with_a_glued_tail():
    kraft = MATERIALS["kraft"]
    assert kraft.layer_thickness_m == 1.3e-4 and not kraft.clings
    assert kraft.interlayer_mu == 0.4
    assert kraft.seam_holds_n_per_m == 3000.0        # about half the web's 5990 N/m


def test_lldpe_is_5_7_um_thick_clings_and_its_clung_tail_holds_as_the_film_does():
    film = MATERIALS["lldpe"]
    assert film.layer_thickness_m == pytest.approx(20e-6 / 3.5) and film.clings
    assert film.seam_holds_n_per_m == pytest.approx(film.break_force_n_per_m)


def test_film_laid_at_another_pre_stretch_weighs_what_came_off_the_roll():
    """The card's film is laid at 250 %: 1 m² of it came off 1/3.5 m² of roll. Laid at 300 %,
    1 m² comes off 1/4 m²: it weighs 3.5/4 as much. Paper, and film at no stated pre-stretch,
    weigh the card's figure."""
    film = MATERIALS["lldpe"]
    assert film.grammage_at(3.0) == pytest.approx(film.grammage_kg_m2 * 3.5 / 4.0)
    assert film.grammage_at(2.5) == pytest.approx(film.grammage_kg_m2)
    assert film.grammage_at(None) == film.grammage_kg_m2
    assert MATERIALS["kraft"].grammage_at(1.0) == MATERIALS["kraft"].grammage_kg_m2


def test_a_custom_card_without_the_fields_gets_the_documented_defaults(wrap_data):
    film = WrapFormat.from_dict(wrap_data({"material": dict(CUSTOM), **LOW_TENSION})).material
    assert film.layer_thickness_m == pytest.approx(0.012 / DENSITY_KG_M3["film"])
    assert film.clings
    assert film.seam_holds_n_per_m == pytest.approx(film.break_force_n_per_m)
    paper = WrapFormat.from_dict(wrap_data({"material": {**CUSTOM_PAPER},
                                            **LOW_TENSION})).material
    assert paper.layer_thickness_m == pytest.approx(0.012 / DENSITY_KG_M3["paper"])
    assert not paper.clings and paper.interlayer_mu == PAPER_INTERLAYER_FRICTION
    assert paper.seam_holds_n_per_m == pytest.approx(GLUED_SEAM_FRACTION
                                                * paper.break_force_n_per_m)


def test_a_custom_card_without_a_relaxation_law_relaxes_as_its_kind(wrap_data):
    """A plant's own paper tested 16 h after wrapping relaxes as paper is assumed to
    (docs/materials.md, P8), not at all; a card that relaxes differently says so, and one that
    does not relax gives `relaxation = {plateau = 1.0}`. Each is written back as read."""
    cards = {"film": {**CUSTOM}, "paper": {**CUSTOM_PAPER},
             "none": {**CUSTOM_PAPER, "relaxation": {"plateau": 1.0}},
             "own": {**CUSTOM_PAPER, "relaxation": {"plateau": 0.9, "terms": [[0.1, 5.0]]}},
             # a term of no amplitude relaxes nothing: allowed, as a card may list it
             "idle": {**CUSTOM_PAPER, "relaxation": {"plateau": 1.0, "terms": [[0.0, 5.0]]}}}
    laws = {}
    for key, table in cards.items():
        wrap = WrapFormat.from_dict(wrap_data({"material": table, **LOW_TENSION}))
        laws[key] = wrap.material.relaxation
        assert WrapFormat.from_dict(wrap.to_dict()).material == wrap.material
    assert laws["film"] == FILM_RELAXATION and laws["paper"] == PAPER_RELAXATION
    assert laws["none"] == NO_RELAXATION and laws["own"].retained(5.0) == pytest.approx(
        0.9 + 0.1 / 2.718281828459045)
    assert laws["idle"].retained(5.0) == 1.0


def test_a_custom_card_takes_the_fields_given_and_writes_them_back(wrap_data):
    table = {**CUSTOM_PAPER, "thickness_m": 2e-4, "interlayer_friction": 0.6,
             "seam_strength_n_per_m": 150.0}
    wrap = WrapFormat.from_dict(wrap_data({"material": table, **LOW_TENSION}))
    card = wrap.material
    assert (card.layer_thickness_m, card.interlayer_mu,
            card.seam_holds_n_per_m) == (2e-4, 0.6, 150.0)
    assert WrapFormat.from_dict(wrap.to_dict()).material == card


def test_a_film_given_a_friction_slides_like_paper(wrap_data):
    table = {**CUSTOM, "interlayer_friction": 0.2}
    card = WrapFormat.from_dict(wrap_data({"material": table, **LOW_TENSION})).material
    assert not card.clings and card.interlayer_mu == 0.2


BAD_CARDS = {
    "zero thickness": ({"thickness_m": 0.0}, "material.thickness_m"),
    "a board, not a web": ({"thickness_m": 0.01}, "material.thickness_m"),
    "negative friction": ({"interlayer_friction": -0.1}, "material.interlayer_friction"),
    "friction of a typo": ({"interlayer_friction": 5.0}, "material.interlayer_friction"),
    "friction as text": ({"interlayer_friction": "high"}, "material.interlayer_friction"),
    "zero seam": ({"seam_strength_n_per_m": 0.0}, "material.seam_strength_n_per_m"),
    "nan seam": ({"seam_strength_n_per_m": float("nan")}, "material.seam_strength_n_per_m"),
    "typo in seam": ({"seam_strenght_n_per_m": 100.0}, "material.seam_strenght_n_per_m"),
}


@pytest.mark.parametrize("fields, field", BAD_CARDS.values(), ids=BAD_CARDS.keys())
def test_a_failure_field_out_of_range_is_one_line_naming_file_and_field(
        fields, field, wrap_file, assert_input_error):
    path = wrap_file({"material": {**CUSTOM, **fields}, **LOW_TENSION})
    with pytest.raises(InputError) as info:
        WrapFormat.from_toml(path)
    assert_input_error(info.value, str(path), field)


def test_a_card_s_look_is_its_kind_s_so_a_custom_paper_is_drawn_as_paper(wrap_data):
    """The look travels with the card: named cards by their kind, a custom card by the kind it
    declares, whatever its name says ("film" named like paper is drawn as film)."""
    assert set(LOOKS) == set(MATERIAL_KINDS)
    assert MATERIALS["kraft"].look == LOOKS["paper"] and MATERIALS["lldpe"].look == LOOKS["film"]
    paper = {"material": {**CUSTOM_PAPER, "name": "brown wrap"}, **LOW_TENSION}
    film = {"material": {**CUSTOM, "kind": "film", "name": "kraft-coloured paper film"},
            **LOW_TENSION}
    assert WrapFormat.from_dict(wrap_data(paper)).material.look == LOOKS["paper"]
    assert WrapFormat.from_dict(wrap_data(film)).material.look == LOOKS["film"]
    # paper hides the labels under it in a recording, film shows them
    assert LOOKS["paper"].recorded_alpha > 0.5 > LOOKS["film"].recorded_alpha


def test_a_custom_web_that_hardens_as_steeply_as_it_stretches_is_refused(wrap_data):
    """A hardening slope of 1 x the elastic one or more would never yield (the element clamps
    the plastic modulus to ~1e17) while its break force assumes it does."""
    table = {**CUSTOM, "hardening_ratio": 2.0}
    with pytest.raises(InputError, match="hardening_ratio: must be < 1"):
        WrapFormat.from_dict(wrap_data({"material": table, **LOW_TENSION}))

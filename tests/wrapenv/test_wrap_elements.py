"""The wrap's element law (wrapenv/wrap_elements.py): elastic, slack in compression, permanent
stretch, tearing, and how much less a web bears where it bends round a load's edge, each
checked against a hand computation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wrapenv.material import MATERIALS, Material
from wrapenv.wrap_elements import bend_curvature, bend_factor, element_set

# -- the element law ----------------------------------------------------------------------


def element(k=1000.0, yield_n=10.0, break_n=50.0, hardening=0.1):
    """One element whose web has stiffness k and yield/break forces for one metre of web."""
    return element_set(k_web_n_per_m=np.array([k]),
                       material_strength=(yield_n, break_n, hardening), web_m=np.array([1.0]),
                       pretension_n=np.zeros(1), mass_kg=np.ones(1), height_m=np.zeros(1),
                       length_m=np.ones(1), give_n_per_m=1e12)


def test_element_is_elastic_below_yield_and_never_pushes():
    e = element()
    assert e.force(np.array([0.005]), np.zeros(1))[0] == pytest.approx(5.0, rel=1e-6)
    assert e.force(np.array([-0.01]), np.zeros(1))[0] == 0.0  # compressed: slack, no push
    assert e.plastic_m[0] == 0.0


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


# -- edges: the web bends round them ------------------------------------------------------

KRAFT = MATERIALS["kraft"]
#: Standard (not extensible) sack kraft: breaks at 2.5 % (docs/materials.md, section 1).
STANDARD_KRAFT = Material("standard kraft", 0.09, 4.0e5, 0.008, 0.025, 0.1125, 0.6, "paper",
                          thickness_m=1.3e-4)


def test_round_a_carton_edge_extensible_kraft_bears_a_sixth_less(edge_factor):
    # t = 130 um round r = 3 mm: outer fibre strain 0.13 / 6.13 = 0.02121, leaving
    # 0.07 - 0.02121 = 0.04879 of membrane strain: 3200 + 45000 x (0.04879 - 0.008) = 5035.6 N/m
    # against 5990 N/m flat
    assert edge_factor(KRAFT, 0.003) == pytest.approx(5990.0 / 5035.6, rel=1e-4)


def test_round_a_bottle_the_edge_costs_kraft_about_one_percent(edge_factor):
    # r = 45 mm: 0.13 / 90.13 = 0.001442 of strain, 45000 x 0.001442 = 64.9 N/m less
    assert edge_factor(KRAFT, 0.045) == pytest.approx(5990.0 / (5990.0 - 64.9), rel=1e-4)


def test_film_is_too_thin_and_stretchy_for_an_edge_to_matter(edge_factor):
    assert edge_factor(MATERIALS["lldpe"], 0.003) == pytest.approx(1.0, abs=0.005)


def test_a_knife_edge_costs_at_most_half_the_stretch_to_break(edge_factor):
    # capped bending 0.0125 of 0.025: 3200 + 45000 x (0.0125 - 0.008) = 3402.5 N/m against
    # 3200 + 45000 x 0.017 = 3965 N/m
    assert edge_factor(STANDARD_KRAFT, 1e-5) == pytest.approx(3965.0 / 3402.5, rel=1e-4)
    assert bend_factor(STANDARD_KRAFT, np.array([0.0]))[0] == pytest.approx(1.0)


def test_a_small_kink_bends_a_tensioned_web_less_than_a_corner():
    # D = K t^2 / 12 = 4e5 x 1.69e-8 / 12 = 5.633e-4 N m; under 1000 N/m, l = sqrt(D / T) =
    # 0.7506 mm: a 90 degree corner bends it as sharp as a 3 mm edge (1.571 / 1.501 mm = 1046
    # 1/m > 333 1/m); a 5 degree kink over the same edge only 0.08727 / 1.501 mm = 58.1 1/m
    turn = np.radians([90.0, 5.0])
    kappa = bend_curvature(KRAFT, np.array([0.003, 0.003]), turn, np.array([1000.0, 1000.0]))
    assert kappa[0] == pytest.approx(1 / 0.003)
    assert kappa[1] == pytest.approx(math.radians(5.0) / (2 * math.sqrt(5.6333e-4 / 1000.0)),
                                     rel=1e-3)

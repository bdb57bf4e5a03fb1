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
    # reloaded beyond where it yielded, it goes on along the hardened line: 12 N at 0.03 m
    assert e.force(np.array([0.03]), np.zeros(1))[0] == pytest.approx(12.0, rel=1e-6)


def test_a_small_pull_is_a_pull():
    # 0.5 mm on 1000 N/m: 0.5 N, however small
    assert element().force(np.array([0.0005]), np.zeros(1))[0] == pytest.approx(0.5)


def test_an_element_pulls_from_its_rest_length_not_from_zero():
    """A ring frozen round the load at its rest length: only the stretch past it pulls."""
    e = element()
    e.rest_m[:] = 2.0
    assert e.force(np.array([2.005]), np.zeros(1))[0] == pytest.approx(5.0)
    assert e.force(np.array([1.995]), np.zeros(1))[0] == 0.0


def test_elements_yield_each_by_its_own_overstretch():
    """Two elements of one set: the one 0.5 N past its 10 N yield takes a permanent stretch
    (bilinear: 10 + 100 x 0.0005 = 10.05 N, and 0.5 / (1000 + 111.1) = 0.45 mm of it
    permanent); the one below yield stays elastic."""
    e = element_set(k_web_n_per_m=np.full(2, 1000.0), material_strength=(10.0, 50.0, 0.1),
                    web_m=np.ones(2), pretension_n=np.zeros(2), mass_kg=np.ones(2),
                    height_m=np.zeros(2), length_m=np.ones(2), give_n_per_m=1e12)
    force = e.force(np.array([0.0105, 0.008]), np.zeros(2))
    assert force == pytest.approx([10.05, 8.0], rel=1e-6)
    assert e.plastic_m == pytest.approx([0.0105 - 10.05 / 1000.0, 0.0], abs=1e-9)


def test_an_element_whose_seam_opened_is_slack_however_far_it_is_pulled():
    e = element()
    e.opened[0] = True
    assert e.force(np.array([0.005]), np.ones(1))[0] == 0.0
    assert e.last_n[0] == 0.0


def test_an_element_just_short_of_its_breaking_force_holds():
    # 10 N at yield, then 100 N/m: 11.9 N at 29 mm, short of 12 N
    e = element(k=1000.0, yield_n=10.0, break_n=12.0, hardening=0.1)
    assert e.force(np.array([0.029]), np.zeros(1))[0] == pytest.approx(11.9, rel=1e-6)
    assert not e.torn[0]
    assert e.peak[0] == pytest.approx(11.9 / 12.0, rel=1e-6)


def test_element_tears_at_its_breaking_force_and_stays_torn():
    e = element(k=1000.0, yield_n=10.0, break_n=12.0, hardening=0.1)
    assert e.force(np.array([0.05]), np.zeros(1))[0] == 0.0
    assert e.torn[0]
    assert e.force(np.array([0.001]), np.zeros(1))[0] == 0.0


def test_an_element_stands_for_its_metres_of_web_in_series_with_the_load_s_give():
    """Half a metre of web (yield 5 N, break 25 N of its 10 and 50 N/m) on a load that gives
    as stiffly as the web: in series, 500 N/m; 2.5 N at 5 mm, yielding from 10 mm."""
    e = element_set(k_web_n_per_m=np.array([1000.0]), material_strength=(10.0, 50.0, 0.1),
                    web_m=np.array([0.5]), pretension_n=np.zeros(1), mass_kg=np.ones(1),
                    height_m=np.zeros(1), length_m=np.ones(1), give_n_per_m=1000.0)
    assert (e.yield_force_n[0], e.break_force_n[0]) == (5.0, 25.0)
    assert e.force(np.array([0.005]), np.zeros(1))[0] == pytest.approx(2.5)
    assert e.force(np.array([0.01]), np.zeros(1))[0] == pytest.approx(5.0)
    assert e.plastic_m[0] == pytest.approx(0.0, abs=1e-12)


def test_an_element_is_damped_at_its_share_of_critical_but_never_pushes():
    """c = 2 zeta sqrt(k m): 1000 N/m joining 4 kg at 0.2 of critical, 25.3 N s/m; a slack
    element is not damped, and damping never turns a pull into a push."""
    e = element_set(k_web_n_per_m=np.array([1000.0]), material_strength=(10.0, 50.0, 0.1),
                    web_m=np.ones(1), pretension_n=np.zeros(1), mass_kg=np.array([4.0]),
                    height_m=np.zeros(1), length_m=np.ones(1), give_n_per_m=1e12,
                    damping_ratio=0.2)
    c = 2 * 0.2 * math.sqrt(1000.0 * 4.0)
    assert e.force(np.array([0.005]), np.array([0.1]))[0] == pytest.approx(5.0 + 0.1 * c)
    assert e.force(np.array([0.005]), np.array([-1.0]))[0] == 0.0
    assert e.force(np.array([-0.005]), np.array([0.1]))[0] == 0.0


def test_an_edge_tears_the_web_at_its_share_of_the_breaking_force_and_records_the_peak():
    """Round an edge that makes it bear a fifth (factor 5), the element tears once its
    12 N (10 N at yield, then 100 N/m for 20 mm) times 5 passes its 50 N: the place bore 10 N
    (50 / 5), its utilisation capped at 1, at the time given."""
    e = element()
    e.force(np.array([0.005]), np.zeros(1), edge=5.0, t_s=0.1)
    assert e.peak[0] == pytest.approx(5.0 * 5 / 50) and e.peak_t_s[0] == 0.1
    assert not e.torn[0]
    assert e.force(np.array([0.03]), np.zeros(1), edge=5.0, t_s=0.2)[0] == 0.0
    assert e.torn[0] and e.peak[0] == 1.0 and e.peak_t_s[0] == 0.2
    assert e.peak_force_n[0] == pytest.approx(10.0)


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


def test_a_web_still_elastic_after_the_bend_bears_its_stiffness_times_what_is_left():
    """A stiff paper yielding late (at 2 % of its 2.5 %): a bend of 1 % leaves 1.5 %, still
    elastic, 4e5 x 0.015 = 6000 N/m against its 8000 + 40000 x 0.005 = 8200 N/m flat."""
    late = Material("late-yielding paper", 0.09, 4.0e5, 0.02, 0.025, 0.1, 0.6, "paper",
                    thickness_m=1.3e-4)
    assert bend_factor(late, np.array([0.01]))[0] == pytest.approx(8200.0 / 6000.0)


def test_a_small_kink_bends_a_tensioned_web_less_than_a_corner():
    # D = K t^2 / 12 = 4e5 x 1.69e-8 / 12 = 5.633e-4 N m; under 1000 N/m, l = sqrt(D / T) =
    # 0.7506 mm: a 90 degree corner bends it as sharp as a 3 mm edge (1.571 / 1.501 mm = 1046
    # 1/m > 333 1/m); a 5 degree kink over the same edge only 0.08727 / 1.501 mm = 58.1 1/m
    turn = np.radians([90.0, 5.0])
    kappa = bend_curvature(KRAFT, np.array([0.003, 0.003]), turn, np.array([1000.0, 1000.0]))
    assert kappa[0] == pytest.approx(1 / 0.003)
    assert kappa[1] == pytest.approx(math.radians(5.0) / (2 * math.sqrt(5.6333e-4 / 1000.0)),
                                     rel=1e-3)

"""What a run tells about its wrap (wrapenv/wrap_report.py): every place of the envelope, where
it lies on the envelope unrolled, and the most loaded ones as CONTRACTS.md's `wrap.critical`."""

from __future__ import annotations

import numpy as np
import pytest

from tests.wrapenv.conftest import weak_wrap_on_a_slick_unit
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_geometry import CORNER_NAMES, FACE_NAMES, corner_positions_m
from wrapenv.wrap_physics import WrapNet
from wrapenv.wrap_report import CRITICAL_COUNT, Place

UNIT = LoadUnit.from_dict({"pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
                           "stack": {"layers": 2}})
WRAP = WrapFormat.from_dict({"material": "kraft", "web_width_m": 0.5, "band": [
    {"from_m": 0.0, "to_m": 0.804, "layers": 2, "tension_n": 250.0}]})


@pytest.fixture(scope="module")
def report():
    """The wrap laid on the 2-layer unit as stacked and one step taken, the top layer's +x+y
    corner bundle pushed 5 mm out along its diagonal."""
    layout = UNIT.layout()
    net = WrapNet(WRAP, layout)
    pos = np.array([(0, 0, layout.pallet_size_m[2] / 2)] + [b.centre_m for b in layout.bundles])
    rot = np.repeat(np.eye(3)[None], len(pos), axis=0)
    net.freeze(pos, rot)
    bulged = pos.copy()
    bulged[1 + [b.name for b in layout.bundles].index("L2C4R4"), :2] += 0.005 / np.sqrt(2)
    zero = np.zeros_like(pos)
    net.forces(bulged, rot, zero, zero, t_s=0.25)
    return net.report()


def test_every_place_of_the_envelope_is_reported_once(report):
    """5 rings (pallet round, two per layer): 4 corners and 4 faces each. Between consecutive
    rings, the 4 faces' diagonals (they cross from bundle to bundle) and, where the rings' corners
    sit on different bodies (pallet to layer 1, layer 1 to layer 2; a layer's two rings share
    its corner bundles), 4 verticals. One seam."""
    kinds = [p.element for p in report.places]
    assert kinds.count("ring") == 5 * 8
    assert kinds.count("vertical") == 2 * 4 and kinds.count("diagonals") == 4 * 4
    assert kinds.count("seam") == 1
    keys = [(p.element, p.where, round(p.height_m, 4)) for p in report.places]
    assert len(keys) == len(set(keys))


def test_places_lie_on_the_unrolled_envelope(report):
    corners = corner_positions_m(UNIT.layout())
    for p in report.places:
        if p.where in CORNER_NAMES:
            assert p.s0_m == p.s1_m == corners[CORNER_NAMES.index(p.where)]
        elif p.where in FACE_NAMES:
            f = FACE_NAMES.index(p.where)
            assert (p.s0_m, p.s1_m) == (corners[f], corners[f + 1])
        assert 0.0 <= p.z0_m <= p.height_m <= p.z1_m <= UNIT.load_height_m


def test_the_seam_runs_round_the_whole_perimeter_at_the_rings_it_closes(report):
    """The tail's joint is glued across the web's width at the last revolution: a place round
    the whole outline (s from 0 to the perimeter), between its lowest and highest ring."""
    (seam,) = [p for p in report.places if p.element == "seam"]
    rings = sorted({p.height_m for p in report.places if p.element == "ring"})
    assert (seam.s0_m, seam.s1_m) == (0.0, corner_positions_m(UNIT.layout())[-1])
    assert seam.z0_m in rings and seam.z1_m in rings
    assert seam.z0_m <= seam.height_m <= seam.z1_m
    assert not seam.opened


def test_a_place_is_written_to_a_tenth_of_a_millimetre_and_a_centinewton():
    place = Place("ring", "corner -x-y", 0.123456, 0.987654, 123.4567, 0.1234567,
                  0.0, 0.0, 0.123456, 0.123456)
    assert place.to_json() == {"height_m": 0.1235, "where": "corner -x-y",
                               "utilisation": 0.9877, "t_s": 0.1235, "element": "ring",
                               "force_n": 123.46}
    untimed = Place("seam", "seam", 0.5, 1.0, 80.0, None, 0.0, 4.0, 0.4, 0.6, opened=True)
    assert untimed.to_json()["t_s"] is None and untimed.to_json()["opened"] is True
    assert "torn" not in untimed.to_json()


def test_the_pushed_corner_stretches_its_layer_s_rings_most_loaded_at_their_corners(report):
    """Pushed out along its diagonal, the corner bundle lengthens both rings of the top layer
    by about 2 x 5 mm / sqrt(2): their tension rises and their corners, where the web bends
    round the bundles' edges, are the most loaded places."""
    top = report.critical[:4]
    assert all(p.element == "ring" and p.where in CORNER_NAMES for p in top)
    assert {round(p.height_m, 4) for p in top} <= {0.5565, 0.7215}
    assert all(p.t_s == 0.25 for p in top)


def test_critical_is_the_most_loaded_places_as_the_contract_writes_them(report):
    critical = report.to_json()["critical"]
    assert len(critical) == CRITICAL_COUNT
    use = [c["utilisation"] for c in critical]
    assert use == sorted(use, reverse=True) and use[0] == round(report.peak_utilisation, 4)
    for c in critical:
        assert {"height_m", "where", "utilisation", "t_s"} <= set(c)
        assert c["where"] in (*CORNER_NAMES, *FACE_NAMES, "seam")
    assert report.to_json()["opened"] is False and report.to_json()["torn"] is False


def test_a_torn_ring_is_torn_where_it_bore_its_limit_its_corners_not_its_faces():
    """A web that breaks at 0.4 % strain, the same corner pushed 10 mm out: the top layer's two
    rings tear. A ring carries one tension, which its corners bear less well (the web bends
    round the bundles' edges): they reached the limit and are the places marked torn, while
    its flat faces bore less and are not."""
    _, weak = weak_wrap_on_a_slick_unit()
    layout = UNIT.layout()
    net = WrapNet(weak, layout)
    pos = np.array([(0, 0, layout.pallet_size_m[2] / 2)] + [b.centre_m for b in layout.bundles])
    rot = np.repeat(np.eye(3)[None], len(pos), axis=0)
    net.freeze(pos, rot)
    pos[1 + [b.name for b in layout.bundles].index("L2C4R4"), :2] += 0.01 / np.sqrt(2)
    zero = np.zeros_like(pos)
    net.forces(pos, rot, zero, zero, t_s=0.25)
    report = net.report()
    torn_rings = {0.5565, 0.7215}
    assert torn_rings <= set(report.torn_at_m)
    for p in report.places:
        if p.element == "ring" and round(p.height_m, 4) in torn_rings:
            at_corner = p.where in CORNER_NAMES
            assert p.torn == at_corner and (p.utilisation == 1.0) == at_corner, p

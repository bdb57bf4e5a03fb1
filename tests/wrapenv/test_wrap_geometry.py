"""Where the wrap's elements lie (wrapenv/wrap_geometry.py): rings round the convex hull of a
layer, so every bundle the web touches is held, whatever the layout; each ring's share of web,
tension and give, and each panel's stiffness and web, computed by hand on a column of two
bundles; where each place lies round the outline; which rings the seam closes."""

from __future__ import annotations

import numpy as np
import pytest

from wrapenv import wrap_geometry as geometry
from wrapenv.load import LoadUnit
from wrapenv.wrap import Band, WrapFormat
from wrapenv.wrap_geometry import CORNER_NAMES, FACE_NAMES, Panels, Ring


def _unit(positions: list[list[float]], layers: int = 1) -> LoadUnit:
    """PET bundles at `positions` on a EUR pallet, `layers` high."""
    return LoadUnit.from_dict({
        "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": layers, "pattern": "explicit", "positions": positions}})


def _kraft(height_m: float, layers: int) -> WrapFormat:
    """Kraft at 250 N a layer on a 0.5 m web, from the sled to `height_m`."""
    return WrapFormat.from_dict({"material": "kraft", "web_width_m": 0.5, "band": [
        {"from_m": 0.0, "to_m": height_m, "layers": layers, "tension_n": 250.0}]},
        load_height_m=height_m)


def test_a_staggered_bundle_on_the_hull_but_off_the_bounding_box_is_on_the_ring():
    """Bundles at (-0.4, -0.25), (0.2, -0.15), (0.4, 0.25): the middle one's -y face lies
    0.1 m inside the layer's bounding box, yet its +x-y corner (0.34, -0.245) sticks out of the
    line from the first bundle's (-0.26, -0.345) to the third's (0.54, 0.155): the web bends
    round it."""
    layout = _unit([[-0.4, -0.25], [0.2, -0.15], [0.4, 0.25]]).layout()
    # the layer's lower ring (ring 0 is the pallet's)
    ring = geometry.ring_specs(_kraft(layout.load_height_m, 1), layout)[1]
    assert sorted({body for body, _ in ring.slots}) == [1, 2, 3]
    assert any(np.allclose(xy, (0.34, -0.245)) for xy in ring.rest_xy)
    # without it the web would run straight from (-0.26, -0.345) to (0.54, 0.155), at x = 0.34
    # through y = -0.345 + 0.6 / 0.8 x 0.5 = 0.030: 0.275 m inside that corner
    a, b = np.array((-0.26, -0.345)), np.array((0.54, 0.155))
    assert a[1] + (0.34 - a[0]) / (b[0] - a[0]) * (b[1] - a[1]) == pytest.approx(0.030)


# --- one bundle a layer, two layers: every element by hand ------------------------------------
# EUR pallet 1.2 x 0.8 x 0.144 m, a 0.28 x 0.19 x 0.33 m bundle on its centre and one on that:
# 0.804 m tall. Two Kraft layers at 250 N on a 0.5 m web all the way up: 1000 N per metre of
# height. Kraft's card: 4e5 N/m per unit strain, CD 0.6 of it, in-plane shear 0.25 of it.

_COLUMN = _unit([[0.0, 0.0]], layers=2)


def _column() -> tuple[WrapFormat, list[Ring]]:
    wrap = _kraft(0.804, 2)
    return wrap, geometry.ring_specs(wrap, _COLUMN.layout())


def test_rings_stand_at_a_quarter_and_three_quarters_of_each_layer_and_share_its_height():
    """The pallet round at mid-height, then two rings a layer, each standing for the half of
    the layer nearest it: web and laid tension over that share (2 layers x 0.165 m = 0.33 m of
    web, 1000 N/m x 0.165 m = 165 N)."""
    _, rings = _column()
    assert [r.z_m for r in rings] == pytest.approx([0.072, 0.2265, 0.3915, 0.5565, 0.7215])
    assert [r.share_m for r in rings] == [pytest.approx(s) for s in (
        (0.0, 0.144), (0.144, 0.309), (0.309, 0.474), (0.474, 0.639), (0.639, 0.804))]
    assert [r.web_m for r in rings] == pytest.approx([0.288] + [0.33] * 4)
    assert [r.tension_n for r in rings] == pytest.approx([144.0] + [165.0] * 4)
    assert [r.perimeter_m for r in rings] == pytest.approx([4.0] + [0.94] * 4)
    assert [sorted({b for b, _ in r.slots}) for r in rings] == [[0], [1], [1], [2], [2]]


def test_a_ring_covers_only_heights_a_band_covers():
    """A band over the top layer only: no pallet round, no ring on the bottom layer."""
    wrap, _ = _column()
    top_only = WrapFormat(wrap.material, 0.5, (Band(0.474, 0.804, 2, 250.0),), "kraft")
    rings = geometry.ring_specs(top_only, _COLUMN.layout())
    assert [r.z_m for r in rings] == pytest.approx([0.5565, 0.7215])


def test_a_ring_s_give_is_its_four_edges_dents_in_series():
    """Each 90 degree edge shortens the perimeter by 2 sin 45° x its dent, which is
    2 T sin 45° / k_edge: 4 sin²45° = 2 of compliance per k_edge, four edges 8 / k_edge. A PET
    edge dents at 6e5 N/m per metre, over the ring's 0.165 m: k_edge 99 000 N/m, the ring's
    give 12 375 N/m."""
    _, rings = _column()
    stiffness = np.array([1e6, 6e5, 6e5])   # pallet, bundle 1, bundle 2 (N/m per metre)
    assert geometry.ring_give(rings[1], stiffness) == pytest.approx(99_000 / 8)
    # the pallet's corners at 1e6 over 0.144 m
    assert geometry.ring_give(rings[0], stiffness) == pytest.approx(1e6 * 0.144 / 8)


def _panels(wrap: WrapFormat, rings: list[Ring]) -> Panels:
    """`panel_specs` with node ids numbered ring by ring, slot by slot, as the net does."""
    ids = np.cumsum([0] + [len(r.slots) for r in rings])
    corners = [[int(ids[i]) + j for j in r.corner_slots] for i, r in enumerate(rings)]
    node_body = np.array([b for r in rings for b, _ in r.slots])
    outline = geometry.corner_positions_m(_COLUMN.layout())
    return geometry.panel_specs(wrap, rings, corners, node_body, outline)


def test_panels_join_rings_on_different_bodies_only():
    """Pallet to bottom layer and bottom layer to top: four corner verticals and eight face
    diagonals each; the two rings on one bundle are joined by the bundle itself."""
    wrap, rings = _column()
    panels = _panels(wrap, rings)
    assert [tuple(r) for r in panels.rings] == [(0, 1)] * 12 + [(2, 3)] * 12
    assert panels.where[:4] == list(CORNER_NAMES)
    assert panels.where[4:12] == [f for f in FACE_NAMES for _ in range(2)]


def test_a_corner_vertical_is_the_web_of_half_the_two_faces_beside_it_stretched_across_the_gap():
    """Between the layers: 0.165 m apart, corners above each other. It stands for half of each
    face beside it (0.28 and 0.19 m: 0.235 m of web a layer) in the web's cross direction:
    k = 4e5 x 0.6 x 2 layers x 0.235 m / 0.165 m."""
    wrap, rings = _column()
    panels = _panels(wrap, rings)
    joint = [e for e in range(len(panels.where)) if tuple(panels.rings[e]) == (2, 3)][:4]
    assert panels.k_web_n_per_m[joint] == pytest.approx([4e5 * 0.6 * 2 * 0.235 / 0.165] * 4)
    assert panels.web_m[joint] == pytest.approx([0.6 * 2 * 0.235] * 4)
    assert panels.rise[joint] == pytest.approx([1.0] * 4)
    assert panels.height_m[joint] == pytest.approx([0.474] * 4)
    assert panels.s_m[joint] == pytest.approx(np.array([[0.0, 0.0], [0.28, 0.28], [0.47, 0.47],
                                                        [0.75, 0.75]]))


def test_a_corner_vertical_from_the_pallet_runs_slanted_to_the_bundle_s_corner():
    """From the pallet's corner (-0.6, -0.4) at 0.072 m to the bundle's (-0.14, -0.095) at
    0.2265 m: 0.5519 m across, 0.1545 m up, 0.5731 m long. Its faces are the mean of the
    pallet's and the bundle's (0.74 and 0.495 m), so it stands for 0.6175 m of web a layer."""
    wrap, rings = _column()
    panels = _panels(wrap, rings)
    across = np.hypot(0.46, 0.305)
    length = np.hypot(across, 0.1545)
    assert panels.k_web_n_per_m[0] == pytest.approx(4e5 * 0.6 * 2 * 0.6175 / length)
    assert panels.rise[0] == pytest.approx(0.1545 / length)


def test_a_face_diagonal_is_the_face_s_web_in_shear():
    """Face -y between the layers: corner to opposite corner, 0.28 m across and 0.165 m up
    (cos = 0.28 / 0.325). A face of web w wide and h tall sheared by a diagonal stretch d has
    shear strain d / (h cos): the diagonal's stiffness is G x layers x w / (h cos²), G the
    card's 0.25 x 4e5. Each of the two diagonals stands for half the face's web along it."""
    wrap, rings = _column()
    panels = _panels(wrap, rings)
    face = [e for e in range(len(panels.where)) if tuple(panels.rings[e]) == (2, 3)
            and panels.where[e] == "face -y"]
    cos = 0.28 / np.hypot(0.28, 0.165)
    assert panels.k_web_n_per_m[face] == pytest.approx(
        [0.25 * 4e5 * 2 * 0.28 / (0.165 * cos**2)] * 2)
    assert panels.web_m[face] == pytest.approx([2 * 0.28 / (2 * cos)] * 2)
    assert panels.rise[face] == pytest.approx([0.165 / np.hypot(0.28, 0.165)] * 2)
    assert panels.s_m[face] == pytest.approx(np.array([[0.0, 0.28]] * 2))


def test_slots_on_a_face_are_placed_along_it():
    """Two bundles side by side along x: their touching corners lie on the faces -y and +y at
    x = 0, halfway along the 0.56 m faces: s = 0.28 m on face -y (from corner -x-y at 0) and
    0.75 + 0.28 = 1.03 m on face +y (which runs from corner +x+y at 0.56 + 0.19 m)."""
    ring = geometry.ring_specs(_kraft(0.474, 1), _unit([[-0.14, 0.0], [0.14, 0.0]]).layout())[1]
    placed = sorted(zip(ring.places, np.round(ring.s_m, 6), strict=True))
    assert placed == [("corner +x+y", 0.75), ("corner +x-y", 0.56), ("corner -x+y", 1.31),
                      ("corner -x-y", 0.0), ("face +y", 1.03), ("face +y", 1.03),
                      ("face -y", 0.28), ("face -y", 0.28)]


def test_the_seam_lies_under_the_last_revolution_s_web():
    """The program's last pass is its top wraps: web from 0.354 to 0.854 m on the 0.804 m
    column, over the rings at 0.3915, 0.5565 and 0.7215 m. Where no ring lies under it, the
    ring nearest its middle (0.604 m) holds the tail."""
    wrap, rings = _column()
    program = WrapFormat.from_dict({"material": "kraft", "web_width_m": 0.5, "program": {
        "bottom_wraps": 2, "bottom_tension_n": 250.0, "up_overlap": 0.5,
        "middle_tension_n": 250.0, "top_wraps": 2, "top_tension_n": 250.0}},
        load_height_m=0.804)
    assert geometry.seam_rings(program, rings) == [2, 3, 4]
    assert geometry.seam_rings(program, rings[:2]) == [1]


def test_each_slot_s_neighbours_are_the_nearest_active_slots_round_the_ring():
    """A torn slot drops out of its ring: the web runs from the slot before it to the one
    after, round the ring's end."""
    active = np.array([[True, False, True, True],
                       [False, True, False, False]])
    prev, nxt = geometry.hull_neighbours(active)
    assert prev.tolist() == [[3, 0, 0, 2], [1, 1, 1, 1]]
    assert nxt.tolist() == [[2, 2, 3, 0], [1, 1, 1, 1]]

"""The bench described once (wrapenv/scene.py): bodies by name, the two numberings (world
order and state rows) and where each body stands; the renderer shows the same bodies."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wrapenv.load import LoadUnit
from wrapenv.render import Renderer, SideCamera
from wrapenv.scene import (
    BUNDLES,
    PALLET,
    SLED_DECK_M,
    STOPPER_SIZE_M,
    BenchScene,
    bundle_row,
)

EXAMPLE_2 = "examples/pet_2layer_columnar.toml"


@pytest.fixture(scope="module")
def layout():
    unit = LoadUnit.from_toml(EXAMPLE_2)
    return dataclasses.replace(unit, pallet_stopper=True).layout()


def test_bodies_are_named_in_world_order_sled_pallet_bundles_then_the_stopper(layout):
    scene = BenchScene(layout)
    names = [b.name for b in scene.bodies]
    assert names == ["sled", "pallet", *(b.name for b in layout.bundles), "stopper"]
    assert [scene.index(n) for n in names] == list(range(len(names)))
    assert scene.index("L1C1R1") == names.index("L1C1R1")
    with pytest.raises(ValueError, match="no body 'L9C1R1'"):
        scene.index("L9C1R1")


def test_state_rows_are_the_moving_bodies_pallet_first(layout):
    scene = BenchScene(layout)
    assert scene.state_index("pallet") == PALLET == 0
    rows = np.arange(len(scene.moving))
    bundle_rows = [scene.state_index(b.name) for b in layout.bundles]
    assert bundle_rows == rows[BUNDLES].tolist() == [bundle_row(k) for k in
                                                     range(len(layout.bundles))]
    # each state row's world body is the body of that name
    for b in layout.bundles:
        assert scene.moving[scene.state_index(b.name)] == scene.index(b.name)
    with pytest.raises(ValueError, match="no moving body 'sled'"):
        scene.state_index("sled")


def test_the_stopper_takes_the_sled_s_friction_every_other_body_its_own(layout):
    scene = BenchScene(layout)
    parts = scene.parts.tolist()
    assert parts[scene.index("stopper")] == scene.index("sled")
    own = [i for i, b in enumerate(scene.bodies) if b.name != "stopper"]
    assert [parts[i] for i in own] == own
    assert scene.n_parts == 2 + len(layout.bundles)


def test_geometry_deck_top_at_zero_pallet_on_it_stopper_behind_the_rear_face(layout):
    scene = BenchScene(layout)
    sled, pallet, stopper = (scene.body(n) for n in ("sled", "pallet", "stopper"))
    px, py, pz = layout.pallet_size_m
    assert sled.centre_m[2] + sled.size_m[2] / 2 == pytest.approx(0.0)
    assert sled.size_m[2] == SLED_DECK_M and sled.mass_kg == 0.0
    # the deck reaches 2 m beyond the pallet on every side: a bundle that falls off lands on it
    assert sled.size_m[:2] == pytest.approx((px + 4.0, py + 4.0))
    assert pallet.centre_m[2] - pallet.size_m[2] / 2 == pytest.approx(0.0)
    assert pallet.mass_kg == layout.pallet_mass_kg
    # the bar stands on the deck, across the pallet's width, against its rear (-x) face: a lab
    # sets the pallet against it (docs/materials.md, "the stop bar")
    t, h = STOPPER_SIZE_M
    assert stopper.size_m == (t, py, h) and stopper.mass_kg == 0.0
    assert stopper.centre_m[2] - h / 2 == pytest.approx(0.0)
    front = stopper.centre_m[0] + t / 2
    assert front == pytest.approx(-px / 2)
    for b in layout.bundles:
        body = scene.body(b.name)
        assert (body.centre_m, body.size_m, body.mass_kg, body.layer) == (
            b.centre_m, b.size_m, b.mass_kg, b.layer)
        # a simulation starts each layer 0.1 mm higher than the one below
        assert body.start_centre_m[2] - b.centre_m[2] == pytest.approx(1e-4 * b.layer)


def test_neighbouring_bundles_of_a_layer_differ_in_colour(layout):
    scene = BenchScene(layout)
    first = sorted((b for b in layout.bundles if b.layer == 1 and b.name.endswith("R1")),
                   key=lambda b: b.centre_m[0])
    colours = [scene.body(b.name).rgba for b in first]
    assert all(a != b for a, b in zip(colours, colours[1:], strict=False))
    above = next(b for b in layout.bundles if b.layer == 2 and b.name.startswith("L2C1"))
    assert scene.body(above.name).rgba != scene.body(first[0].name).rgba


def test_the_renderer_shows_the_scene_s_bodies_where_it_puts_them(layout):
    """Pixel by pixel, the renderer's body mask names the scene's body at its projected centre:
    the stopper, the pallet, a bundle; the deck below them."""
    camera = SideCamera(width=400, height=200, px_per_m=100.0, origin_px=(200.0, 170.0))
    scene = BenchScene(layout)
    pos = np.array([scene.bodies[w].centre_m for w in scene.moving.tolist()])
    rot = np.repeat(np.eye(3)[None], len(pos), 0)
    with Renderer(layout, camera) as renderer:
        _, mask = renderer.masked_frame(pos[PALLET], rot[PALLET], pos[BUNDLES], rot[BUNDLES])
    for name in ("stopper", "pallet", "L2C1R1", "sled"):
        centre = np.array(scene.body(name).centre_m)
        (u, v), = camera.project(centre[None])
        assert mask[round(v), round(u)] == scene.index(name), name

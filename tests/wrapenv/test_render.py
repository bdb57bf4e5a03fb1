"""Rendered frames (wrapenv/render.py): the side camera's pixel mapping, moving bodies, the wrap
overlay and its tears, and that renderers give their Bullet clients back.

Small images only (320 x 200 at 100 px/m), so the whole file runs in a few seconds.
"""

from __future__ import annotations

import resource

import numpy as np
import pytest

from wrapenv.bullet import BulletWorld, rotation_matrices
from wrapenv.load import LoadUnit
from wrapenv.render import (
    Renderer,
    SideCamera,
    WrapOverlay,
    quaternions,
    torn_net,
)
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet
from wrapenv.wrap_report import WrapReport

EXAMPLE_2 = "examples/pet_2layer_columnar.toml"
#: Non-integer origin, so the mapping is checked below pixel level too.
CAMERA = SideCamera(width=320, height=200, px_per_m=100.0, origin_px=(160.3, 170.6))
WHITE = 255  # TinyRenderer's background


def wrap_format(material: str = "kraft") -> WrapFormat:
    return WrapFormat.from_dict({
        "material": material, "web_width_m": 0.5,
        "band": [{"from_m": 0.0, "to_m": 0.804, "layers": 2, "tension_n": 250.0}],
    })


@pytest.fixture(scope="module")
def layout():
    return LoadUnit.from_toml(EXAMPLE_2).layout()


def rest(layout):
    """(pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot) of the unit as stacked."""
    n = len(layout.bundles)
    return (np.array([0.0, 0.0, layout.pallet_size_m[2] / 2]), np.eye(3),
            np.array([b.centre_m for b in layout.bundles]), np.repeat(np.eye(3)[None], n, 0))


def extent(mask: np.ndarray) -> tuple[int, int, int, int]:
    """(first column, last column, first row, last row) of a boolean mask."""
    rows, cols = np.nonzero(mask)
    return cols.min(), cols.max(), rows.min(), rows.max()


def box_pixels(size, centre, camera: SideCamera, sled_x_m: float = 0.0):
    with BulletWorld(1 / 240, 1) as world:
        world.add_box(size, centre, 0.0, 0.5, rgba=(1, 0, 0, 1))
        image = world.camera_image(camera.width, camera.height, camera.view_matrix(sled_x_m),
                                   camera.projection_matrix())
    red = (image[..., 0] > 120) & (image[..., 1] < 60) & (image[..., 2] < 60)
    return image, red


@pytest.mark.parametrize("sled_x_m", [0.0, -0.37])
def test_tinyrenderer_image_matches_project(sled_x_m):
    size, centre = (0.43, 0.2, 0.317), (0.52, 0.1, 0.41)
    image, red = box_pixels(size, centre, CAMERA, sled_x_m)
    assert image.shape == (200, 320, 3) and image.dtype == np.uint8
    corners = np.array(centre) + np.array([[sx, 0, sz] for sx in (-1, 1) for sz in (-1, 1)]) \
        * np.array(size) / 2
    uv = CAMERA.project(corners, sled_x_m)
    left, right, top, bottom = extent(red)
    # pixel c is covered when its centre u = c is inside the box
    assert abs(left - uv[:, 0].min()) <= 2 and abs(right - uv[:, 0].max()) <= 2
    assert abs(top - uv[:, 1].min()) <= 2 and abs(bottom - uv[:, 1].max()) <= 2
    assert abs((right - left) - 100 * size[0]) <= 2


def test_project_is_the_contract_mapping():
    u0, v0 = CAMERA.origin_px
    uv = CAMERA.project([[0, 5, 0], [1.0, -3, 0.5]], sled_x_m=0.25)
    np.testing.assert_allclose(uv, [[u0 + 25, v0], [u0 + 125, v0 - 50]])


def test_quaternions_invert_bench_rotations():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(200, 4))
    q[:4] = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0.7071, 0.7071, 0, 1e-7]]  # half-turns
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    back = quaternions(rotation_matrices(q))
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", back, q)), 1.0, atol=1e-9)


def test_frame_shape_and_moving_a_bundle_moves_its_pixels(layout):
    pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot = rest(layout)
    # the top layer's leftmost bundle of the front row: nothing is left of it
    k = next(i for i, b in enumerate(layout.bundles) if b.name == "L2C1R1")
    row = round(CAMERA.project([layout.bundles[k].centre_m])[0, 1])
    moved = bundle_pos_m.copy()
    moved[k, 0] -= 0.1
    with Renderer(layout, CAMERA) as renderer:
        before = renderer.frame(pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot)
        after = renderer.frame(pallet_pos_m, pallet_rot, moved, bundle_rot)
        shifted = renderer.frame(pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot, sled_x_m=0.1)
    assert before.shape == (200, 320, 3) and before.dtype == np.uint8

    def left_edge(image):
        return np.flatnonzero(np.any(image[row] != WHITE, axis=1)).min()

    b = layout.bundles[k]
    expected = CAMERA.project([[b.centre_m[0] - b.size_m[0] / 2, 0, b.centre_m[2]]])[0, 0]
    assert abs(left_edge(before) - expected) <= 2
    assert abs((left_edge(before) - left_edge(after)) - 100 * 0.1) <= 2
    assert abs((left_edge(shifted) - left_edge(before)) - 100 * 0.1) <= 2


def load_box(layout):
    """Pixel slices (rows, columns) of the load above the pallet, a margin inside its outline."""
    xs = [b.centre_m[0] + s * b.size_m[0] / 2 for b in layout.bundles for s in (-1, 1)]
    lo = CAMERA.project([[min(xs), 0, layout.pallet_size_m[2]]])[0]
    hi = CAMERA.project([[max(xs), 0, layout.load_height_m]])[0]
    return slice(int(hi[1]) + 3, int(lo[1]) - 3), slice(int(lo[0]) + 3, int(hi[0]) - 3)


def test_wrap_is_visible_and_a_torn_wrap_is_not(layout):
    state = rest(layout)
    net = WrapNet(wrap_format("kraft"), layout)
    with Renderer(layout, CAMERA) as renderer:
        plain = renderer.frame(*state)
        wrapped = renderer.frame(*state, wrap_net=net)
        net.rings.torn[:] = True
        net.panels.torn[:] = True
        torn = renderer.frame(*state, wrap_net=net)
    rows, cols = load_box(layout)
    changed = np.any(plain != wrapped, axis=2)
    assert changed[rows, cols].mean() > 0.95  # the web covers the load's side
    assert not changed[:rows.start - 10].any()  # and nothing above the load
    tint = wrapped[rows, cols].reshape(-1, 3).mean(0) - plain[rows, cols].reshape(-1, 3).mean(0)
    assert tint[0] > 20 and tint[2] < -10  # blue bundles under light-brown paper turn warmer
    np.testing.assert_array_equal(torn, plain)


def test_one_torn_ring_leaves_a_gap_and_film_has_its_own_tint(layout):
    state = rest(layout)
    kraft, film = WrapNet(wrap_format("kraft"), layout), WrapNet(wrap_format("lldpe"), layout)
    r = 2  # the first layer's upper ring
    kraft.rings.torn[r] = True
    band = WrapOverlay(kraft).bands[r]
    with Renderer(layout, CAMERA) as renderer:
        plain = renderer.frame(*state)
        wrapped = renderer.frame(*state, wrap_net=kraft)
        filmed = renderer.frame(*state, wrap_net=film)
    rows, cols = load_box(layout)
    gap = slice(*np.sort(CAMERA.project([[0, 0, band[1]], [0, 0, band[0]]])[:, 1]
                         .round().astype(int) + [2, -2]))
    np.testing.assert_array_equal(wrapped[gap, cols], plain[gap, cols])
    assert np.any(wrapped[rows, cols] != plain[rows, cols])
    mean = [img[rows, cols].reshape(-1, 3).mean(0) for img in (wrapped, filmed)]
    assert np.abs(mean[0] - mean[1]).max() > 5


def _at_rest(layout, report: WrapReport | None) -> Trace:
    pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot = rest(layout)
    n = len(layout.bundles)
    return Trace(level_g=0.5, load_height_m=layout.load_height_m,
                 names=tuple(b.name for b in layout.bundles), bottom_z_m=np.zeros(n),
                 t_s=np.zeros(1), sled_accel_mps2=np.zeros(1),
                 pallet_pos_m=pallet_pos_m[None], pallet_rot=pallet_rot[None],
                 bundle_pos_m=bundle_pos_m[None], bundle_rot=bundle_rot[None], wrap=report)


def test_a_wrap_is_drawn_torn_at_every_height_its_run_reported_torn(layout):
    """A trace records the heights that tore, not the elements: every ring and panel at such a
    height is drawn torn, and no other."""
    wrap = wrap_format()
    net = WrapNet(wrap, layout)
    ring_at = round(float(net.rings.height_m[2]), 4)      # a ring, and a panel (between rings)
    panel_at = round(float(np.unique(net.panels.height_m)[2]), 4)
    torn = torn_net(wrap, layout, _at_rest(layout, WrapReport((ring_at, panel_at), 1.3, 0.02)))
    for elements in (torn.rings, torn.panels):
        assert elements.torn.any()
        assert np.array_equal(elements.torn, np.isin(np.round(elements.height_m, 4),
                                                     (ring_at, panel_at)))
    intact = torn_net(wrap, layout, _at_rest(layout, WrapReport((), 0.4, 0.0)))
    assert not intact.rings.torn.any() and not intact.panels.torn.any()


def test_a_trace_frame_is_the_frame_of_its_sample(layout):
    pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot = rest(layout)
    net = WrapNet(wrap_format(), layout)
    n = len(layout.bundles)
    moved = bundle_pos_m + [0.03, 0.0, 0.0]
    trace = Trace(
        level_g=0.3, load_height_m=layout.load_height_m,
        names=tuple(b.name for b in layout.bundles), bottom_z_m=np.zeros(n),
        t_s=np.array([0.0, 0.05]), sled_accel_mps2=np.zeros(2),
        pallet_pos_m=np.stack([pallet_pos_m] * 2), pallet_rot=np.stack([pallet_rot] * 2),
        bundle_pos_m=np.stack([bundle_pos_m, moved]), bundle_rot=np.stack([bundle_rot] * 2),
    )
    with Renderer(layout, CAMERA) as renderer:
        one = renderer.frame(pallet_pos_m, pallet_rot, moved, bundle_rot, net)
        np.testing.assert_array_equal(renderer.trace_frame(trace, 1, net), one)


def test_renderers_close_their_clients(layout):
    state = rest(layout)
    net = WrapNet(wrap_format(), layout)
    renderer = Renderer(layout, CAMERA)
    for _ in range(50):
        renderer.frame(*state, wrap_net=net)
    renderer.close()
    renderer.close()
    assert renderer.world.closed
    with pytest.raises(RuntimeError):
        renderer.frame(*state)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    for _ in range(30):
        with Renderer(layout, CAMERA) as r:
            r.frame(*state, wrap_net=net)
        assert r.world.closed
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    assert grown_mb < 50

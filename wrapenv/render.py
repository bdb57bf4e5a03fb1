"""Frames of the bench as the recordings' side camera sees it, with the soft wrap drawn over.

The rigid bodies are drawn by PyBullet's TinyRenderer (the CPU renderer DIRECT mode has) through
an orthographic projection built by hand, so every point lands where CONTRACTS.md's camera model
puts it, u = u0 + px_per_m * x and v = v0 - px_per_m * z, with no perspective to correct for.
The wrap is no body in Bullet (it is forces, `WrapNet`), so it is drawn afterwards with OpenCV:
each ring's share of web as a semi-transparent band with the ring's line through it, and a bridge
between neighbouring bands where the bodies under them have moved apart. Torn elements are left
out, so a tear shows as a gap.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from wrapenv.bullet import BulletWorld
from wrapenv.load import Layout
from wrapenv.scene import BUNDLES, PALLET, BenchScene
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet

#: Opacity of the web in reports (its colours are the material card's look).
WRAP_ALPHA = 0.35
#: Every body's colour in a frame of shading alone (textures are multiplied in).
WHITE_RGBA = (1.0, 1.0, 1.0, 1.0)
#: Where neighbouring bands lost the web between them, each band's edge draws back this far, so
#: the tear is a visible gap even while the bodies still touch.
TEAR_GAP_M = 0.02
_SHIFT = 4  # OpenCV sub-pixel bits: vertices are drawn at 1/16 px
_CONTINUOUS_M = 1e-6


@dataclass(frozen=True)
class SideCamera:
    """The recordings' fixed side camera (CONTRACTS.md, "Recording folder").

    It looks along +y from y = -distance_m and maps world x, z to pixels without perspective:
    u = u0 + px_per_m * x, v = v0 - px_per_m * z with (u0, v0) = `origin_px`. Pixel coordinates
    are OpenCV's: pixel (column c, row r) is centred on u = c, v = r.
    """

    width: int
    height: int
    px_per_m: float
    #: (u0, v0): the pixel the sled frame's origin projects to
    origin_px: tuple[float, float]
    distance_m: float = 5.0

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"image size {self.width}x{self.height} is empty")
        if not (self.px_per_m > 0 and self.distance_m > 0):
            raise ValueError("px_per_m and distance_m must be positive")
        u0, v0 = self.origin_px
        object.__setattr__(self, "origin_px", (float(u0), float(v0)))

    def project(self, points_xyz: np.ndarray | Sequence, sled_x_m: float = 0.0) -> np.ndarray:
        """Pixels (n, 2) of points (n, 3) given in the sled frame; world x = x + sled_x_m."""
        p = np.asarray(points_xyz, float).reshape(-1, 3)
        u0, v0 = self.origin_px
        return np.stack([u0 + self.px_per_m * (p[:, 0] + sled_x_m),
                         v0 - self.px_per_m * p[:, 2]], axis=1)

    def view_matrix(self, sled_x_m: float = 0.0) -> list[float]:
        """Sled frame to eye (OpenGL, column-major): eye x = world x, eye y = z, looking at +y."""
        m = np.array([[1.0, 0, 0, sled_x_m],
                      [0, 0, 1, 0],
                      [0, -1, 0, -self.distance_m],
                      [0, 0, 0, 1]])
        return m.T.ravel().tolist()

    def projection_matrix(self) -> list[float]:
        """Orthographic projection (column-major) that reproduces `project` in TinyRenderer.

        TinyRenderer samples pixel (c, r) at viewport point (c, height - 1 - r), hence the
        `height - 1`. Its depth row is unusual on purpose: TinyRenderer derives near and far
        planes from the matrix as if it were a perspective one, b / (a - 1) and b / (a + 1), and
        discards fragments outside them; with a = -1/2, b = 4 d everything from 8 d in front of
        the camera to 8/3 d behind it is kept, nearer in front of farther.
        """
        w, h, s = self.width, self.height, self.px_per_m
        u0, v0 = self.origin_px
        m = np.array([[2 * s / w, 0, 0, 2 * u0 / w - 1],
                      [0, 2 * s / h, 0, 2 * (h - 1 - v0) / h - 1],
                      [0, 0, -0.5, 4 * self.distance_m],
                      [0, 0, 0, 1]])
        return m.T.ravel().tolist()


def quaternions(rot: np.ndarray) -> np.ndarray:
    """Quaternions (n, 4, Bullet's x y z w) of rotation matrices (n, 3, 3).

    Each is computed from whichever of w, x, y, z is largest, so it stays accurate near
    half-turns too (the inverse of `wrapenv.bullet.rotation_matrices`).
    """
    r = np.asarray(rot, float).reshape(-1, 3, 3)
    m00, m11, m22 = r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]
    d21, d02, d10 = r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]
    s01, s02, s12 = r[:, 0, 1] + r[:, 1, 0], r[:, 0, 2] + r[:, 2, 0], r[:, 1, 2] + r[:, 2, 1]
    # 4 w^2, 4 x^2, 4 y^2, 4 z^2
    squares = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22,
                        1 - m00 + m11 - m22, 1 - m00 - m11 + m22], axis=1)
    case = np.argmax(squares, axis=1)
    rows = np.arange(len(r))
    s = 2 * np.sqrt(np.maximum(squares[rows, case], 1e-12))  # 4 times the largest component
    candidates = np.stack([
        np.stack([d21 / s, d02 / s, d10 / s, s / 4], axis=1),
        np.stack([s / 4, s01 / s, s02 / s, d21 / s], axis=1),
        np.stack([s01 / s, s / 4, s12 / s, d02 / s], axis=1),
        np.stack([s02 / s, s12 / s, s / 4, d10 / s], axis=1),
    ])
    q = candidates[case, rows]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def rest_state(layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """Positions (n, 3) and rotations (n, 3, 3) of the moving bodies as stacked: the state
    arrays `WrapNet.nodes` takes, e.g. for a picture of the unit before a test."""
    scene = BenchScene(layout)
    pos = np.array([scene.bodies[w].centre_m for w in scene.moving.tolist()])
    return pos, np.repeat(np.eye(3)[None], len(pos), axis=0)


def _coverage(net: WrapNet) -> list[tuple[float, float]]:
    """Height intervals the wrap's bands cover, overlapping bands merged."""
    merged: list[list[float]] = []
    for band in sorted(net.wrap.bands, key=lambda b: b.from_m):
        if merged and band.from_m <= merged[-1][1] + _CONTINUOUS_M:
            merged[-1][1] = max(merged[-1][1], band.to_m)
        else:
            merged.append([band.from_m, band.to_m])
    return [(a, b) for a, b in merged]


class WrapOverlay:
    """A `WrapNet` as drawn over a frame.

    Geometry that does not change is computed once: which body-fixed nodes each ring runs
    through, the height of web each ring stands for (its band) and the front corners of each
    pair of neighbouring rings. Tear states are read from the net at every draw.
    """

    def __init__(self, net: WrapNet, alpha: float = WRAP_ALPHA) -> None:
        #: opacity of the web: recordings draw paper nearly opaque and film see-through
        self.alpha = alpha
        self.net = net
        layout = net.layout
        rest_pos, rest_rot = rest_state(layout)
        scene = BenchScene(layout)
        half = np.array([scene.bodies[w].size_m[2] / 2 for w in scene.moving.tolist()])
        spans = np.stack([rest_pos[:, 2] - half, rest_pos[:, 2] + half], axis=1)
        rest = net.nodes(rest_pos, rest_rot)
        self.ring_nodes = [row[row >= 0] for row in net._slots]
        self.bands = self._bands(spans)
        # front corners (-x-y, +x-y) of every ring, for bridges along the face seen by the camera
        corners = []
        for ids in self.ring_nodes:
            xy = rest[ids, :2]
            lo, hi = xy.min(axis=0), xy.max(axis=0)
            corners.append([int(ids[np.argmin(np.linalg.norm(xy - t, axis=1))])
                            for t in ((lo[0], lo[1]), (hi[0], lo[1]))])
        self.corners = corners
        self.bridges: list[tuple[int, np.ndarray]] = []  # (lower ring, panels across the front)
        for i in range(len(self.ring_nodes) - 1):
            if abs(self.bands[i][1] - self.bands[i + 1][0]) > _CONTINUOUS_M:
                continue  # no web joins these bands
            front = set(corners[i]) | set(corners[i + 1])
            elements = np.array([e for e, (a, b) in enumerate(net.panel_nodes)
                                 if a in front and b in front], int)
            self.bridges.append((i, elements))
        look = net.wrap.material.look
        self.fill_rgb, self.line_rgb = look.fill_rgb, look.line_rgb

    def _bands(self, spans: np.ndarray) -> list[tuple[float, float]]:
        """(bottom, top) of the web each ring stands for: the height of the bodies it runs
        round, shared at midpoints between the rings on the same bodies, cut to the bands."""
        z = self.net.ring_heights
        ring_span = [(float(spans[self.net.node_body[ids], 0].min()),
                      float(spans[self.net.node_body[ids], 1].max())) for ids in self.ring_nodes]
        coverage = _coverage(self.net)
        out = []
        for r, (lo, hi) in enumerate(ring_span):
            same = sorted(z[j] for j, s in enumerate(ring_span)
                          if abs(s[0] - lo) < _CONTINUOUS_M and abs(s[1] - hi) < _CONTINUOUS_M)
            k = same.index(z[r])
            bottom = lo if k == 0 else (same[k - 1] + same[k]) / 2
            top = hi if k == len(same) - 1 else (same[k] + same[k + 1]) / 2
            covered = max(coverage, key=lambda c: min(c[1], top) - max(c[0], bottom))
            out.append((max(bottom, covered[0]), min(top, covered[1])))
        return out

    def draw(self, image: np.ndarray, pos: np.ndarray, rot: np.ndarray, camera: SideCamera,
             sled_x_m: float = 0.0) -> np.ndarray:
        """`image` with the wrap blended over it; `pos`, `rot` are the bodies' states (pallet
        first), as `WrapNet.nodes` takes them."""
        net = self.net
        p = net.nodes(pos, rot)
        up = rot[net.node_body][:, :, 2]  # each node's body z axis: band edges follow tilts
        ring_torn = net.rings.torn
        cut = {}
        for i, elements in self.bridges:
            cut[i] = bool(len(elements) and net.panels.torn[elements].any())

        def edge(r: int, height: float, ids: np.ndarray) -> np.ndarray:
            pts = p[ids] + up[ids] * (height - net.ring_heights[r])
            return _fixed(camera.project(pts, sled_x_m))

        overlay = image.copy()
        fill = tuple(int(c) for c in self.fill_rgb)
        for r, ids in enumerate(self.ring_nodes):
            if ring_torn[r]:
                continue
            lo, hi = self.bands[r]
            if hi <= lo:
                continue  # the ring's share of height and the wrap's bands barely meet
            gap = min(TEAR_GAP_M, (hi - lo) / 4)
            lo += gap if cut.get(r - 1, False) else 0.0
            hi -= gap if cut.get(r, False) else 0.0
            a, b = edge(r, lo, ids), edge(r, hi, ids)
            nxt = np.roll(np.arange(len(ids)), -1)
            for j, k in enumerate(nxt):
                quad = np.array([a[j], a[k], b[k], b[j]])
                cv2.fillPoly(overlay, [quad], fill, cv2.LINE_8, _SHIFT)
        for i, _ in self.bridges:
            if cut[i]:
                continue
            low = edge(i, self.bands[i][1], np.array(self.corners[i]))
            high = edge(i + 1, self.bands[i + 1][0], np.array(self.corners[i + 1]))
            quad = np.array([low[0], low[1], high[1], high[0]])
            cv2.fillPoly(overlay, [quad], fill, cv2.LINE_8, _SHIFT)
        out = cv2.addWeighted(overlay, self.alpha, image, 1 - self.alpha, 0.0)
        thickness = max(1, round(camera.width / 960))
        line = tuple(int(c) for c in self.line_rgb)
        for r, ids in enumerate(self.ring_nodes):
            if not ring_torn[r]:
                ring = _fixed(camera.project(p[ids], sled_x_m))
                cv2.polylines(out, [ring], True, line, thickness, cv2.LINE_AA, _SHIFT)
        return out


def _fixed(uv: np.ndarray) -> np.ndarray:
    """Pixel coordinates as OpenCV's fixed-point vertices (int32, `_SHIFT` fractional bits)."""
    return np.round(uv * (1 << _SHIFT)).astype(np.int32)


class Renderer:
    """One Bullet world holding a layout's bodies, built once and then only moved: frames of a
    video cost a render, not a rebuild. It owns a PyBullet client, so close it (or use it as a
    context manager); `close()` may be called more than once."""

    def __init__(self, layout: Layout, camera: SideCamera, colours: bool = True) -> None:
        self.layout = layout
        self.scene = BenchScene(layout)
        self.camera = camera
        #: False: every body white, so a frame is the shading alone (textures are multiplied in)
        self.colours = colours
        self.world = BulletWorld(timestep_s=1 / 240, solver_iterations=1)
        self._overlay: WrapOverlay | None = None
        try:
            self._build()
        except BaseException:
            self.world.close()
            raise

    def _build(self) -> None:
        """The scene's bodies in world order, all static (frames only move them)."""
        for body in self.scene.bodies:
            self.world.add_box(body.size_m, body.centre_m, 0.0, 0.5,
                               rgba=body.rgba if self.colours else WHITE_RGBA)

    def frame(self, pallet_pos_m: np.ndarray, pallet_rot: np.ndarray, bundle_pos_m: np.ndarray,
              bundle_rot: np.ndarray, wrap_net: WrapNet | None = None,
              sled_x_m: float = 0.0) -> np.ndarray:
        """RGB frame (height, width, 3) uint8 of the unit in the given state (sled frame;
        rotations as 3x3 matrices), the wrap drawn over it when `wrap_net` is given."""
        pos, rot = self._place(pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot)
        cam = self.camera
        image = self.world.camera_image(cam.width, cam.height, cam.view_matrix(sled_x_m),
                                        cam.projection_matrix())
        if wrap_net is None:
            return image
        return self.draw_wrap(image, pos, rot, wrap_net, sled_x_m)

    def masked_frame(self, pallet_pos_m: np.ndarray, pallet_rot: np.ndarray,
                     bundle_pos_m: np.ndarray, bundle_rot: np.ndarray,
                     sled_x_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """The frame without the wrap, and per pixel the world index of the body seen there
        (`BenchScene.index`; -1 background): where textures go."""
        self._place(pallet_pos_m, pallet_rot, bundle_pos_m, bundle_rot)
        cam = self.camera
        return self.world.camera_image_and_mask(cam.width, cam.height, cam.view_matrix(sled_x_m),
                                                cam.projection_matrix())

    def draw_wrap(self, image: np.ndarray, pos: np.ndarray, rot: np.ndarray, wrap_net: WrapNet,
                  sled_x_m: float = 0.0, alpha: float = WRAP_ALPHA) -> np.ndarray:
        """`image` with the wrap drawn over it; `pos`, `rot` are the bodies' states, pallet
        first (as `WrapNet.nodes` takes them)."""
        n = len(self.scene.moving)
        if wrap_net.n_bodies != n:
            raise ValueError(f"the wrap net has {wrap_net.n_bodies} bodies, the layout {n}")
        if self._overlay is None or self._overlay.net is not wrap_net:
            self._overlay = WrapOverlay(wrap_net)
        self._overlay.alpha = alpha
        return self._overlay.draw(image, pos, rot, self.camera, sled_x_m)

    def _place(self, pallet_pos_m: np.ndarray, pallet_rot: np.ndarray, bundle_pos_m: np.ndarray,
               bundle_rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Move the bodies to a state; returns it as the state arrays (positions, rotations)."""
        if self.world.closed:
            raise RuntimeError("the renderer is closed")
        moving = self.scene.moving
        pos, rot = np.empty((len(moving), 3)), np.empty((len(moving), 3, 3))
        pos[PALLET], rot[PALLET] = np.reshape(pallet_pos_m, 3), np.reshape(pallet_rot, (3, 3))
        pos[BUNDLES] = np.reshape(bundle_pos_m, (-1, 3))
        rot[BUNDLES] = np.reshape(bundle_rot, (-1, 3, 3))
        quat = quaternions(rot)
        for row, w in enumerate(moving.tolist()):
            self.world.set_pose(w, pos[row], quat[row])
        return pos, rot

    def trace_frame(self, trace: Trace, sample_index: int,
                    wrap_net: WrapNet | None = None) -> np.ndarray:
        """The frame of one sample of a bench run. A trace does not record when elements tore:
        the wrap is drawn with the net's tear state as it is now."""
        i = sample_index
        return self.frame(trace.pallet_pos_m[i], trace.pallet_rot[i], trace.bundle_pos_m[i],
                          trace.bundle_rot[i], wrap_net)

    def close(self) -> None:
        """Disconnect the Bullet client; safe to call more than once."""
        self.world.close()

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def fitting_camera(layout: Layout, width: int, height: int) -> SideCamera:
    """A side camera of this size whose scale fits the unit, with room for it to move: centred
    horizontally, the sled frame's origin 85 % down the image (a loaded pallet fills the upper
    part)."""
    origin = (width / 2, 0.85 * height)
    across = 0.8 * width / (layout.pallet_size_m[0] + 0.2)
    up = (origin[1] - 0.08 * height) / (layout.load_height_m + 0.05)
    return SideCamera(width, height, float(math.floor(min(across, up))), origin)


def torn_net(wrap: WrapFormat, layout: Layout, trace: Trace) -> WrapNet:
    """The wrap net to draw after a run: a trace records where the wrap tore (heights), not
    which element, so every element at a reported height is drawn torn."""
    net = WrapNet(wrap, layout)
    if trace.wrap is not None and trace.wrap.torn:
        torn = np.array(trace.wrap.torn_at_m)
        for elements in (net.rings, net.panels):
            elements.torn |= np.isin(np.round(elements.height_m, 4), torn)
    return net

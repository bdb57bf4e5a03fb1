"""The bench as the side camera films it, for synthetic recordings (`calibration.synth`).

Each frame is rendered with TinyRenderer (shading and which body each pixel shows), textured
with procedural prints (`calibration.textures`) warped onto each visible face, wrapped, marked
with ArUco codes, then degraded like a camera does: lighting drift, blur, sensor noise; then
encoded as Motion-JPEG.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration import textures
from calibration.camera_setup import MarkerSpec
from wrapenv.load import Layout
from wrapenv.render import Renderer, SideCamera
from wrapenv.scene import BUNDLES, PALLET, PALLET_NAME, SLED, STOPPER, BenchScene, Body
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet

#: Textures are drawn at this many times the camera's scale, then filtered down by the warp.
TEXTURE_OVERSAMPLING = 2.0
BLUR_SIGMA_PX = 0.6
NOISE_GREY = 2.0
LIGHT_DRIFT = 0.05
#: Codec and quality: Motion-JPEG from OpenCV's own writer (see `write_video`).
FOURCC, JPEG_QUALITY = "MJPG", 100


@dataclass(frozen=True)
class States:
    """Poses at the video's frame times, in the sled frame, as the state arrays
    (`wrapenv.scene`: pallet, then bundles); and the sled's x."""

    t_s: np.ndarray        # (F,)
    pos_m: np.ndarray      # (F, moving bodies, 3): the state arrays (`wrapenv.scene`)
    rot: np.ndarray        # (F, moving bodies, 3, 3)
    sled_x_m: np.ndarray   # (F,)


def drawn_size_m(markers: MarkerSpec) -> float:
    """The side of the markers synth draws, which it always states (setup.toml may not)."""
    if markers.size_m is None:
        raise ValueError("synth draws markers of a stated size")
    return markers.size_m


def web_alpha(wrap: WrapFormat) -> float:
    """How opaque the web is drawn: the material card's look (paper hides the labels under
    it, film shows them)."""
    return wrap.material.look.recorded_alpha


def _face_affine(camera: SideCamera, centre: np.ndarray, rot: np.ndarray, sled_x_m: float,
                 face_centre: tuple[float, float, float], face_m: tuple[float, float],
                 texture_shape: tuple[int, ...]) -> np.ndarray:
    """2x3 map from a face texture's pixels to image pixels. The face (local x across, local z
    up, centred at `face_centre` in the body frame) is a plane seen by an orthographic camera,
    so the map is affine; pixel centres are OpenCV's (texture pixel a spans a - 1/2 .. a + 1/2)."""
    h, w = texture_shape[:2]
    sx, sz = face_m[0] / w, face_m[1] / h  # metres per texture pixel
    fx, fy, fz = face_centre
    # local point of texture pixel (a, b): (fx - wx/2 + (a + 1/2) sx, fy, fz + wz/2 - (b + 1/2) sz)
    origin_local = np.array([fx - face_m[0] / 2 + sx / 2, fy, fz + face_m[1] / 2 - sz / 2])
    p0 = centre + rot @ origin_local
    da, db = rot[:, 0] * sx, -rot[:, 2] * sz
    k = camera.px_per_m
    u0, v0 = camera.origin_px
    return np.array([[k * da[0], k * db[0], u0 + k * (p0[0] + sled_x_m)],
                     [-k * da[2], -k * db[2], v0 - k * p0[2]]])


def _roi(camera: SideCamera, m: np.ndarray, shape: tuple[int, ...]
         ) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1) of the image pixels a warped texture may touch, or None if off-image."""
    h, w = shape[:2]
    corners = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [-0.5, h - 0.5, 1],
                        [w - 0.5, h - 0.5, 1]]) @ m.T
    x0 = max(0, math.floor(corners[:, 0].min()) - 1)
    y0 = max(0, math.floor(corners[:, 1].min()) - 1)
    x1 = min(camera.width, math.ceil(corners[:, 0].max()) + 2)
    y1 = min(camera.height, math.ceil(corners[:, 1].max()) + 2)
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def _warp(texture: np.ndarray, m: np.ndarray, roi: tuple[int, int, int, int]) -> np.ndarray:
    x0, y0, x1, y1 = roi
    shifted = m - np.array([[0, 0, x0], [0, 0, y0]])
    return cv2.warpAffine(texture, shifted, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_REPLICATE)


class Scene:
    """The bench as the camera films it: one renderer, the textures and markers, the camera's
    imperfections. Frames depend only on the states and the seed."""

    def __init__(self, layout: Layout, camera: SideCamera, seed: int, markers: MarkerSpec,
                 wrap: tuple[WrapNet, float] | None) -> None:
        """`wrap`: the web as laid (torn where it tore) and how opaque it is drawn (`web_alpha`),
        None for an unwrapped unit."""
        self.layout, self.camera, self.seed, self.markers = layout, camera, seed, markers
        self.wrap = wrap
        self.scene = scene = BenchScene(layout)
        self.sizes = [b.size_m for b in scene.bodies]
        # antialiasing: the warp samples at half the texture's resolution
        self.textures = [cv2.GaussianBlur(t, (0, 0), TEXTURE_OVERSAMPLING / 2.5).astype(np.float32)
                         for t in _textures(scene.bodies, camera.px_per_m, seed)]
        #: Static bodies (sled, stopper) stand where the scene puts them; the others move.
        self.fixed = {w: (np.array(b.centre_m), np.eye(3))
                      for w, b in enumerate(scene.bodies) if not b.moving}
        #: The row of the state arrays of each moving body (by world index).
        self.state_row = {int(w): s for s, w in enumerate(scene.moving)}
        tpm = TEXTURE_OVERSAMPLING * camera.px_per_m
        aruco = markers.aruco()
        size_m = drawn_size_m(markers)
        side = max(aruco.markerSize + 2, round(size_m * tpm))  # its bits and border
        self.marker_images = {p.id: textures.marker_image(aruco, p.id, side).astype(np.float32)
                              for p in markers.placements}
        self.marker_face = size_m * (1 + 2 * round(side * textures.QUIET_ZONE) / side)
        self.marker_body = {p.id: scene.index(p.object) for p in markers.placements}
        self.wall = textures.wall_texture(camera.width, camera.height, seed).astype(np.float32)
        rng = np.random.default_rng([seed, 7])
        self.drift = (rng.uniform(0.5, 1.0), rng.uniform(0, 2 * math.pi))
        self.renderer = Renderer(layout, camera, colours=False)

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.renderer.close()

    def _pose(self, j: int, pos: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre and rotation (sled frame) of world body j; pos, rot are the state arrays."""
        if j in self.fixed:
            return self.fixed[j]
        return pos[self.state_row[j]], rot[self.state_row[j]]

    def _bodies(self, pos: np.ndarray, rot: np.ndarray, sled_x: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Textured bodies over the wall (float RGB), the shading and the body index mask."""
        shade, mask = self.renderer.masked_frame(pos[PALLET], rot[PALLET], pos[BUNDLES],
                                                  rot[BUNDLES], sled_x)
        out = self.wall.copy()
        seen = np.flatnonzero(np.bincount(mask.ravel() + 1)[1:])
        for j in seen:
            centre, r = self._pose(int(j), pos, rot)
            size = self.sizes[j]
            tex = self.textures[j]
            m = _face_affine(self.camera, centre, r, sled_x, (0.0, -size[1] / 2, 0.0),
                             (size[0], size[2]), tex.shape)
            roi = _roi(self.camera, m, tex.shape)
            if roi is None:
                continue
            x0, y0, x1, y1 = roi
            sel = mask[y0:y1, x0:x1] == j
            lit = _warp(tex, m, roi) * (shade[y0:y1, x0:x1, :1] / 255.0)
            out[y0:y1, x0:x1][sel] = lit[sel]
        return out, shade, mask

    def _draw_markers(self, image: np.ndarray, shade: np.ndarray, mask: np.ndarray,
                      pos: np.ndarray, rot: np.ndarray, sled_x: float) -> None:
        """Markers where their object is in view at the marker's centre, lit as that face."""
        for p in self.markers.placements:
            j = self.marker_body[p.id]
            centre, r = self._pose(j, pos, rot)
            face = (p.offset_m[0], -self.sizes[j][1] / 2, p.offset_m[1])
            tex = self.marker_images[p.id]
            m = _face_affine(self.camera, centre, r, sled_x, face,
                             (self.marker_face, self.marker_face), tex.shape)
            uc, vc = (m @ np.array([(tex.shape[1] - 1) / 2, (tex.shape[0] - 1) / 2, 1.0]))
            iu, iv = round(uc), round(vc)
            if not (0 <= iu < self.camera.width and 0 <= iv < self.camera.height) \
                    or mask[iv, iu] != j:
                continue
            roi = _roi(self.camera, m, tex.shape)
            if roi is None:
                continue
            x0, y0, x1, y1 = roi
            cover = cv2.warpAffine(np.ones(tex.shape[:2], np.float32),
                                   m - np.array([[0, 0, x0], [0, 0, y0]]), (x1 - x0, y1 - y0),
                                   flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
            cover = cover[..., None]
            lit = _warp(tex, m, roi) * (shade[iv, iu, 0] / 255.0)
            image[y0:y1, x0:x1] = image[y0:y1, x0:x1] * (1 - cover) + lit * cover

    def _camera_effects(self, image: np.ndarray, index: int, t_s: float, duration_s: float
                        ) -> np.ndarray:
        """Lighting drift (gain within +-5 %), lens blur and sensor noise, seeded per frame."""
        cycles, phase = self.drift
        gain = 1 + LIGHT_DRIFT * math.sin(2 * math.pi * cycles * t_s / max(duration_s, 1e-9)
                                          + phase)
        blurred = cv2.GaussianBlur(image * np.float32(gain), (0, 0), BLUR_SIGMA_PX)
        rng = np.random.default_rng([self.seed, 6, index])
        noisy = blurred + rng.standard_normal(image.shape, np.float32) * np.float32(NOISE_GREY)
        return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)

    def frame(self, s: States, i: int) -> np.ndarray:
        """Frame i (RGB uint8) as the camera records it."""
        pos, rot, sled_x = s.pos_m[i], s.rot[i], float(s.sled_x_m[i])
        image, shade, mask = self._bodies(pos, rot, sled_x)
        if self.wrap is not None:
            net, alpha = self.wrap
            drawn = np.clip(np.rint(image), 0, 255).astype(np.uint8)
            drawn = self.renderer.draw_wrap(drawn, pos, rot, net, sled_x, alpha)
            image = drawn.astype(np.float32)
        self._draw_markers(image, shade, mask, pos, rot, sled_x)
        return self._camera_effects(image, i, float(s.t_s[i]), float(s.t_s[-1]))

    def frames(self, s: States, progress: Callable[[int, int], None] | None = None
               ) -> Iterator[np.ndarray]:
        for i in range(len(s.t_s)):
            yield self.frame(s, i)
            if progress:
                progress(i + 1, len(s.t_s))

    def template(self, s: States) -> np.ndarray:
        """The front of bundle L1C1R1 (or the first bundle) at rest as the camera sees it,
        unwrapped and without noise: what a template matcher looks for."""
        names = [b.name for b in self.layout.bundles]
        b = self.layout.bundles[names.index("L1C1R1") if "L1C1R1" in names else 0]
        image, _, _ = self._bodies(s.pos_m[0], s.rot[0], float(s.sled_x_m[0]))
        image = cv2.GaussianBlur(image, (0, 0), BLUR_SIGMA_PX)
        centre = s.pos_m[0, self.scene.state_index(b.name)]
        half = np.array([[-1, 0, 1], [1, 0, -1]]) * np.array(b.size_m) / 2
        (ua, va), (ub, vb) = self.camera.project(centre + half, float(s.sled_x_m[0]))
        crop = image[math.ceil(va) + 1:math.floor(vb), math.ceil(ua) + 1:math.floor(ub)]
        return np.clip(np.rint(crop), 0, 255).astype(np.uint8)


def _textures(bodies: tuple[Body, ...], px_per_m: float, seed: int) -> list[np.ndarray]:
    """The print on each body's front face: the sled's deck, the pallet's blocks, a label
    per bundle (one design per face size, varied per bundle), the stopper's dark steel."""
    tpm = TEXTURE_OVERSAMPLING * px_per_m
    designs: dict[tuple[float, float], np.ndarray] = {}
    out = []
    k = 0  # bundle number, varying its print
    for b in bodies:
        face = (b.size_m[0], b.size_m[2])
        if b.name == SLED:
            out.append(textures.deck_texture(face, tpm, seed))
        elif b.name == PALLET_NAME:
            out.append(textures.pallet_texture(face, tpm, seed))
        elif b.name == STOPPER:
            out.append(np.full((max(2, round(face[1] * tpm)), max(2, round(face[0] * tpm)), 3),
                               45, np.uint8))
        else:
            if face not in designs:
                designs[face] = textures.label_design(face, tpm, seed)
            out.append(textures.bundle_texture(designs[face], seed, k))
            k += 1
    return out


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float, size: tuple[int, int]
                ) -> int:
    """Encode RGB frames; returns how many. Motion-JPEG from OpenCV's own encoder, the one that
    honours the quality setting (FFmpeg's ignores it): every frame is coded on its own, and
    textures keep their sub-pixel position where mp4v (no quality control) smears motion."""
    writer = cv2.VideoWriter(str(path), cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter.fourcc(*FOURCC),
                             fps, size)
    if not (writer.isOpened() and writer.set(cv2.VIDEOWRITER_PROP_QUALITY, JPEG_QUALITY)):
        writer.release()  # an opened writer holds the file and its encoder
        raise RuntimeError(f"OpenCV cannot write {FOURCC} video at quality {JPEG_QUALITY}"
                           f" to {path}")
    count = 0
    try:
        for frame in frames:
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
            count += 1
    finally:
        writer.release()
    return count


def png(rgb: np.ndarray) -> bytes:
    ok, data = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return data.tobytes()

"""Synthetic recordings of bench tests whose ground truth is known (issue 5).

No real ESTL footage exists yet, so the tracker and the calibration are measured on recordings
made from the bench itself: one level is simulated (`wrapenv.bench.run_level`), the sled's motion is
integrated from the pulse, and the side camera's frames are rendered with TinyRenderer (shading and
which body each pixel shows), textured with procedural prints (`calibration.textures`), wrapped,
marked with ArUco codes, then degraded like a camera does: lighting drift, blur, sensor noise.
The true poses of every object the tracker must follow go to `truth.json`.

The recording starts with `pre_roll_s` of the unit standing still, then the pulse (t = pre-roll
is the pulse's start) until the unit rests. World x = sled x + x in the sled frame.
"""

from __future__ import annotations

import fcntl
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration import textures
from calibration.camera_setup import MarkerPlacement, MarkerSpec, write_setup
from calibration.recording import (
    LOAD,
    WRAP,
    ObjectTrack,
    Recording,
    SledProfile,
    Truth,
    write_profile,
    write_truth,
)
from wrapenv.bench import SLED_DECK_M, SLED_MARGIN_M, STOPPER_SIZE_M, SimSettings, run_level
from wrapenv.config import InputError, check_output_folder, write_atomic
from wrapenv.load import PAIRS, Friction, FrictionPair, Layout, LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.render import Renderer, SideCamera, is_paper, torn_net
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_physics import WrapNet

MARKER_DICTIONARY = "DICT_4X4_50"
#: Sled markers this far beyond the pallet's ends (a 1.2 m pallet: x = -1.0 and +1.0 m).
SLED_MARKER_REACH_M = 0.4
#: Opacity of the web: paper hides the labels under it, film shows them.
PAPER_ALPHA, FILM_ALPHA = 0.9, 0.3
#: Empty image border round the whole test, as a fraction of the image's width and height.
MARGIN_FRACTION = 0.04
#: Textures are drawn at this many times the camera's scale, then filtered down by the warp.
TEXTURE_OVERSAMPLING = 2.0
BLUR_SIGMA_PX = 0.6
NOISE_GREY = 2.0
LIGHT_DRIFT = 0.05
#: Image sides (px) a recording may have [A]: from 64 (the test is then a few pixels: it is made
#: but nothing in it can be tracked) to a DCI 4K camera's width; beyond, a frame's float buffers
#: (0.2 GB each at 4096 x 4096) run to gigabytes.
SIZE_RANGE_PX = (64, 4096)
#: Highest frame rate (fps): a high-speed camera's [A] (the source paper filmed at 20 fps);
#: a test's few seconds are then thousands of frames, already an hour to render.
MAX_FPS = 1000.0
#: Longest still pre-roll (s) before the pulse [A].
MAX_PRE_ROLL_S = 10.0
#: A recording is written in a hidden folder `.{name}.XXXX{STAGING_SUFFIX}` beside it, then renamed.
STAGING_SUFFIX = ".synth-partial"
#: Codec, file and container: Motion-JPEG at this quality (see `write_video`).
FOURCC, VIDEO_NAME, JPEG_QUALITY = "MJPG", "video.avi", 100


@dataclass(frozen=True)
class _States:
    """Poses at the video's frame times, in the sled frame, pallet first; and the sled's x."""

    t_s: np.ndarray        # (F,)
    pos: np.ndarray        # (F, 1 + n, 3)
    rot: np.ndarray        # (F, 1 + n, 3, 3)
    sled_x_m: np.ndarray   # (F,)


def synthesize(load: LoadUnit, out_dir: str | Path, *, wrap: WrapFormat | None = None,
               level_g: float = 0.4, seed: int = 0, size: tuple[int, int] = (1920, 1200),
               fps: float = 20.0, friction_jitter: float = 0.0, pre_roll_s: float = 0.25,
               stiffness_scale: float = 1.0, tension_scale: float = 1.0,
               marker_size_m: float = 0.06, settings: SimSettings | None = None,
               progress: Callable[[int, int], None] | None = None) -> Recording:
    """Simulate one level of `load` and write its recording folder to `out_dir` (which must not
    exist or be empty). `friction_jitter` draws the true friction of each pair from the load's
    values times U(1 - j, 1 + j) (seeded); the wrap's stiffness and tension are scaled as a
    calibration would find them. load.toml and wrap.toml hold the load and wrap as given, the
    truth holds what was simulated; `progress(frame, frames)` is called as each frame is
    written. Returns the recording as `Recording.read` reads it."""
    out_dir = Path(out_dir)
    _check_arguments(out_dir, size, fps, friction_jitter, pre_roll_s, marker_size_m)
    pulse = PulseProfile(level_g)
    friction = _jittered(load.friction, friction_jitter, seed)
    layout = load.with_friction(friction).layout()
    true_wrap = wrap.scaled(stiffness_scale, tension_scale) if wrap is not None else None
    if true_wrap is not None:
        true_wrap.check_fits(layout.load_height_m, "wrap")
    trace = run_level(layout, pulse, settings or SimSettings(), true_wrap)
    if not trace.valid:
        raise ValueError(f"the simulation became unphysical ({trace.invalid_reason})")
    n_pre = round(pre_roll_s * fps)
    profile = _sled_profile(trace, n_pre / fps)
    states = _states(trace, profile, n_pre, fps)
    markers = _markers(layout, wrap is not None, marker_size_m)
    camera = _fit_camera(layout, states, markers, size)
    params = {
        "level_g": level_g, "seed": seed, "fps": fps, "pre_roll_s": n_pre / fps,
        "friction_jitter": friction_jitter,
        "friction": {name: {"static": friction.pair(name).static,
                            "kinetic": friction.pair(name).kinetic} for name in PAIRS},
        "wrap": None if wrap is None else {"material": wrap.material_key,
                                           "stiffness_scale": stiffness_scale,
                                           "tension_scale": tension_scale},
        "pallet_slip_m": trace.pallet_slip_m(),
        "size": list(size),
    }
    truth = Truth(params, _tracks(layout, states))
    with _staging(out_dir) as tmp:
        scene = _Scene(layout, camera, seed, markers,
                       torn_net(true_wrap, layout, trace) if true_wrap is not None else None,
                       None if wrap is None else (PAPER_ALPHA if is_paper(wrap) else FILM_ALPHA))
        with scene:
            write_video(tmp / VIDEO_NAME, scene.frames(states, progress), fps, size)
            write_atomic(tmp / "template.png", _png(scene.template(states)))
        write_profile(tmp, profile)
        write_setup(tmp, fps, camera.px_per_m, camera.origin_px,  # type: ignore[arg-type]
                    markers, "template.png")
        write_atomic(tmp / LOAD, load.to_toml().encode())
        if wrap is not None:
            write_atomic(tmp / WRAP, wrap.to_toml().encode())
        write_truth(tmp, truth)
    return Recording.read(out_dir)


@contextmanager
def _staging(out_dir: Path) -> Iterator[Path]:
    """A hidden folder beside `out_dir` to write the recording in, renamed to `out_dir` when
    the block ends and removed if it raises: the recording appears whole or not at all. The
    folder is locked while this process lives, so staging folders of runs that were killed
    (nothing unwinds SIGKILL) are told from running ones and removed here."""
    parent = out_dir.parent
    parent.mkdir(parents=True, exist_ok=True)
    _remove_stale_staging(parent)
    tmp = Path(tempfile.mkdtemp(dir=parent, prefix=f".{out_dir.name}.", suffix=STAGING_SUFFIX))
    lock = os.open(tmp, os.O_RDONLY)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        umask = os.umask(0)
        os.umask(umask)
        tmp.chmod(0o777 & ~umask)  # mkdtemp makes it private; a recording is an ordinary folder
        yield tmp
        if out_dir.exists():
            out_dir.rmdir()  # empty, checked before the work
        tmp.rename(out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        os.close(lock)


def _remove_stale_staging(parent: Path) -> None:
    """Staging folders in `parent` whose lock no live process holds."""
    for folder in parent.glob(f".*{STAGING_SUFFIX}"):
        try:
            fd = os.open(folder, os.O_RDONLY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue  # a running synth's
        else:
            shutil.rmtree(folder, ignore_errors=True)
        finally:
            os.close(fd)


def _check_arguments(out_dir: Path, size: tuple[int, int], fps: float, jitter: float,
                     pre_roll_s: float, marker_size_m: float) -> None:
    check_output_folder(out_dir, "")
    low, high = SIZE_RANGE_PX
    if not (len(size) == 2 and all(isinstance(v, int) and low <= v <= high for v in size)):
        raise InputError("arguments", "size", f"must be two whole numbers >= {low} and "
                         f"<= {high} (got {size})")
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise InputError("arguments", "fps", f"must be > 0 and <= {MAX_FPS:g} (got {fps})")
    if not (math.isfinite(jitter) and 0 <= jitter < 1):
        raise InputError("arguments", "friction_jitter", f"must be in [0, 1) (got {jitter})")
    if not (math.isfinite(pre_roll_s) and 0 <= pre_roll_s <= MAX_PRE_ROLL_S):
        raise InputError("arguments", "pre_roll_s",
                         f"must be >= 0 and <= {MAX_PRE_ROLL_S:g} s (got {pre_roll_s})")
    if not (math.isfinite(marker_size_m) and 0 < marker_size_m <= SLED_DECK_M * 0.75):
        raise InputError("arguments", "marker_size_m",
                         f"must be in (0, {SLED_DECK_M * 0.75:g}] m to fit the sled's side"
                         f" (got {marker_size_m})")


def _jittered(friction: Friction, jitter: float, seed: int) -> Friction:
    """Each pair's static and kinetic coefficients times one factor from U(1 - j, 1 + j), so
    static >= kinetic still holds."""
    rng = np.random.default_rng([seed, 0])
    factors = rng.uniform(1 - jitter, 1 + jitter, len(PAIRS))
    return Friction(**{name: FrictionPair(float(friction.pair(name).static * f),
                                          float(friction.pair(name).kinetic * f))
                       for name, f in zip(PAIRS, factors, strict=True)})


def _sled_profile(trace: Trace, pre_s: float) -> SledProfile:
    """The sled's motion on the video's time base, integrated as Bullet integrates the bodies
    (semi-implicit Euler, v += a dt then x += v dt), so a body resting on the sled keeps its
    world x exactly: with trapezoids the sled would drift ~v dt / 2 (4 mm at 2 m/s) from it."""
    dt = float(trace.t_s[1] - trace.t_s[0])
    a = trace.sled_accel_mps2
    vel = np.concatenate([[0.0], np.cumsum(a[1:]) * dt])
    pos = np.cumsum(vel) * dt
    before = pre_s - dt * np.arange(math.ceil(pre_s / dt - 1e-9), 0, -1)
    before = np.unique(np.concatenate([[0.0] if pre_s > 0 else [], before[before > 0]]))
    zeros = np.zeros(len(before))
    return SledProfile(np.concatenate([before, pre_s + trace.t_s]), np.concatenate([zeros, a]),
                       np.concatenate([zeros, vel]), np.concatenate([zeros, pos]))


def _states(trace: Trace, profile: SledProfile, n_pre: int, fps: float) -> _States:
    """Poses at each frame time, interpolated between the trace's samples (rotations
    re-orthonormalised); the unit stands as settled during the pre-roll."""
    frames = n_pre + math.floor(trace.t_s[-1] * fps + 1e-9) + 1
    t = np.arange(frames) / fps
    tau = np.clip(t - n_pre / fps, 0.0, trace.t_s[-1])
    pos = np.concatenate([trace.pallet_pos[:, None], trace.bundle_pos], axis=1)
    rot = np.concatenate([trace.pallet_rot[:, None], trace.bundle_rot], axis=1)
    x = np.interp(tau, trace.t_s, np.arange(len(trace.t_s)))
    i0 = np.minimum(np.floor(x).astype(int), len(trace.t_s) - 2)
    w = (x - i0)[:, None, None]
    p = (1 - w) * pos[i0] + w * pos[i0 + 1]
    r = (1 - w[..., None]) * rot[i0] + w[..., None] * rot[i0 + 1]
    u, _, vt = np.linalg.svd(r)
    return _States(t, p, u @ vt, profile.position_m(t))


def _angle(rot: np.ndarray) -> np.ndarray:
    """Rotation about the camera axis, counter-clockwise in the image (CONTRACTS truth)."""
    return np.arctan2(rot[..., 2, 0], rot[..., 0, 0])


def _tracks(layout: Layout, s: _States) -> dict[str, ObjectTrack]:
    """sled, pallet and the bundles facing the camera (row 1), absolute world coordinates."""
    n = len(s.t_s)
    tracks = {"sled": ObjectTrack(s.t_s, s.sled_x_m.copy(), np.full(n, -SLED_DECK_M / 2),
                                  np.zeros(n))}
    names = ["pallet"] + [b.name for b in layout.bundles]
    for j, name in enumerate(names):
        if j == 0 or name.endswith("R1"):
            tracks[name] = ObjectTrack(s.t_s, s.sled_x_m + s.pos[:, j, 0], s.pos[:, j, 2].copy(),
                                       _angle(s.rot[:, j]))
    return tracks


def _markers(layout: Layout, wrapped: bool, size_m: float) -> MarkerSpec:
    """Two markers on the sled's side, far apart; on a wrapped unit, markers printed on the web
    at the front corners of every layer and of the pallet."""
    px = layout.pallet_size_m[0]
    reach = px / 2 + SLED_MARKER_REACH_M
    placements = [MarkerPlacement(0, "sled", (-reach, 0.0)),
                  MarkerPlacement(1, "sled", (reach, 0.0))]
    if wrapped:
        inset = size_m * (0.5 + textures.QUIET_ZONE) + 0.01
        placements += [MarkerPlacement(2, "pallet", (-(px / 2 - inset), 0.0)),
                       MarkerPlacement(3, "pallet", (px / 2 - inset, 0.0))]
        for layer in sorted({b.layer for b in layout.bundles}):
            front = sorted((b for b in layout.bundles
                            if b.layer == layer and b.name.endswith("R1")),
                           key=lambda b: b.centre_m[0])
            ends = [(front[0], -1.0)] + ([(front[-1], 1.0)] if len(front) > 1 else [])
            for b, side in ends:
                offset = (side * (b.size_m[0] / 2 - inset), b.size_m[2] / 2 - inset)
                placements.append(MarkerPlacement(len(placements), b.name, offset))
    if len(placements) > 50:
        raise InputError("load", "stack", f"needs {len(placements)} markers,"
                         f" {MARKER_DICTIONARY} has 50")
    return MarkerSpec(MARKER_DICTIONARY, size_m, tuple(placements))


def _drawn_size_m(markers: MarkerSpec) -> float:
    """The side of the markers synth draws, which it always states (setup.toml may not)."""
    if markers.size_m is None:
        raise ValueError("synth draws markers of a stated size")
    return markers.size_m


def _fit_camera(layout: Layout, s: _States, markers: MarkerSpec, size: tuple[int, int]
                ) -> SideCamera:
    """The largest whole px_per_m at which the whole test fits the image with margins: every
    box at every frame, the stopper and the sled's markers; the origin centres it."""
    half = np.array([layout.pallet_size_m] + [b.size_m for b in layout.bundles]) / 2
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    corners = np.einsum("fbij,bcj->fbci", s.rot, half[:, None] * signs[None]) + s.pos[:, :, None]
    xs = [(corners[..., 0] + s.sled_x_m[:, None, None]).ravel()]
    zs = [corners[..., 2].ravel(), [-SLED_DECK_M]]
    reach = _drawn_size_m(markers) * (0.5 + textures.QUIET_ZONE)
    for p in markers.placements:
        if p.object == "sled":
            xs.append(s.sled_x_m + p.offset_m[0] - reach)
            xs.append(s.sled_x_m + p.offset_m[0] + reach)
    if layout.pallet_stopper:
        xs.append(s.sled_x_m - layout.pallet_size_m[0] / 2 - STOPPER_SIZE_M[0] - 1e-3)
    x = np.concatenate([np.ravel(v) for v in xs])
    z = np.concatenate([np.ravel(v) for v in zs])
    width, height = size
    k = math.floor(min((1 - 2 * MARGIN_FRACTION) * width / np.ptp(x),
                       (1 - 2 * MARGIN_FRACTION) * height / np.ptp(z)))
    if k < 1:
        raise InputError("arguments", "size", f"{width}x{height} cannot show this test")
    origin = (float(round(width / 2 - k * (x.min() + x.max()) / 2)),
              float(round(height / 2 + k * (z.min() + z.max()) / 2)))
    return SideCamera(width, height, float(k), origin)


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
    u0, v0 = camera.origin_px  # type: ignore[misc]
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


class _Scene:
    """The bench as the camera films it: one renderer, the textures and markers, the camera's
    imperfections. Frames depend only on the states and the seed."""

    def __init__(self, layout: Layout, camera: SideCamera, seed: int, markers: MarkerSpec,
                 wrap_net: WrapNet | None, wrap_alpha: float | None) -> None:
        self.layout, self.camera, self.seed, self.markers = layout, camera, seed, markers
        self.wrap_net, self.wrap_alpha = wrap_net, wrap_alpha
        tpm = TEXTURE_OVERSAMPLING * camera.px_per_m
        px, py, pz = layout.pallet_size_m
        deck = (px + 2 * SLED_MARGIN_M, py + 2 * SLED_MARGIN_M, SLED_DECK_M)
        self.sizes = [deck, layout.pallet_size_m] + [b.size_m for b in layout.bundles]
        designs: dict[tuple[float, float], np.ndarray] = {}
        bundle_textures = []
        for k, b in enumerate(layout.bundles):
            face = (b.size_m[0], b.size_m[2])
            if face not in designs:
                designs[face] = textures.label_design(face, tpm, seed)
            bundle_textures.append(textures.bundle_texture(designs[face], seed, k))
        self.textures = [textures.deck_texture((deck[0], deck[2]), tpm, seed),
                         textures.pallet_texture((px, pz), tpm, seed)] + bundle_textures
        self.fixed = {0: (np.array([0.0, 0.0, -SLED_DECK_M / 2]), np.eye(3))}
        if layout.pallet_stopper:
            t, h = STOPPER_SIZE_M
            self.sizes.append((t, py, h))
            self.textures.append(np.full((max(2, round(h * tpm)), max(2, round(t * tpm)), 3), 45,
                                         np.uint8))
            self.fixed[len(self.sizes) - 1] = (np.array([-px / 2 - t / 2 - 1e-3, 0, h / 2]),
                                               np.eye(3))
        # antialiasing: the warp samples at half the texture's resolution
        self.textures = [cv2.GaussianBlur(t, (0, 0), TEXTURE_OVERSAMPLING / 2.5).astype(np.float32)
                         for t in self.textures]
        aruco = markers.aruco()
        size_m = _drawn_size_m(markers)
        side = max(aruco.markerSize + 2, round(size_m * tpm))  # its bits and border
        self.marker_images = {p.id: textures.marker_image(aruco, p.id, side).astype(np.float32)
                              for p in markers.placements}
        self.marker_face = size_m * (1 + 2 * round(side * textures.QUIET_ZONE) / side)
        names = [b.name for b in layout.bundles]
        self.marker_body = {p.id: 0 if p.object == "sled" else 1 if p.object == "pallet"
                            else 2 + names.index(p.object) for p in markers.placements}
        self.wall = textures.wall_texture(camera.width, camera.height, seed).astype(np.float32)
        rng = np.random.default_rng([seed, 7])
        self.drift = (rng.uniform(0.5, 1.0), rng.uniform(0, 2 * math.pi))
        self.renderer = Renderer(layout, camera, colours=False)

    def __enter__(self) -> _Scene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.renderer.close()

    def _pose(self, j: int, pos: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centre and rotation (sled frame) of world body j; pos, rot hold pallet and bundles."""
        return self.fixed[j] if j in self.fixed else (pos[j - 1], rot[j - 1])

    def _bodies(self, pos: np.ndarray, rot: np.ndarray, sled_x: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Textured bodies over the wall (float RGB), the shading and the body index mask."""
        shade, mask = self.renderer.masked_frame(pos[0], rot[0], pos[1:], rot[1:], sled_x)
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

    def frame(self, s: _States, i: int) -> np.ndarray:
        """Frame i (RGB uint8) as the camera records it."""
        pos, rot, sled_x = s.pos[i], s.rot[i], float(s.sled_x_m[i])
        image, shade, mask = self._bodies(pos, rot, sled_x)
        if self.wrap_net is not None:
            drawn = np.clip(np.rint(image), 0, 255).astype(np.uint8)
            drawn = self.renderer.draw_wrap(drawn, pos, rot, self.wrap_net, sled_x,
                                            self.wrap_alpha)  # type: ignore[arg-type]
            image = drawn.astype(np.float32)
        self._draw_markers(image, shade, mask, pos, rot, sled_x)
        return self._camera_effects(image, i, float(s.t_s[i]), float(s.t_s[-1]))

    def frames(self, s: _States, progress: Callable[[int, int], None] | None = None
               ) -> Iterator[np.ndarray]:
        for i in range(len(s.t_s)):
            yield self.frame(s, i)
            if progress:
                progress(i + 1, len(s.t_s))

    def template(self, s: _States) -> np.ndarray:
        """The front of bundle L1C1R1 (or the first bundle) at rest as the camera sees it,
        unwrapped and without noise: what a template matcher looks for."""
        names = [b.name for b in self.layout.bundles]
        k = names.index("L1C1R1") if "L1C1R1" in names else 0
        image, _, _ = self._bodies(s.pos[0], s.rot[0], float(s.sled_x_m[0]))
        image = cv2.GaussianBlur(image, (0, 0), BLUR_SIGMA_PX)
        b = self.layout.bundles[k]
        centre = s.pos[0, 1 + k]
        half = np.array([[-1, 0, 1], [1, 0, -1]]) * np.array(b.size_m) / 2
        (ua, va), (ub, vb) = self.camera.project(centre + half, float(s.sled_x_m[0]))
        crop = image[math.ceil(va) + 1:math.floor(vb), math.ceil(ua) + 1:math.floor(ub)]
        return np.clip(np.rint(crop), 0, 255).astype(np.uint8)


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float, size: tuple[int, int]
                ) -> int:
    """Encode RGB frames; returns how many. Motion-JPEG from OpenCV's own encoder, the one that
    honours the quality setting (FFmpeg's ignores it): every frame is coded on its own, and
    textures keep their sub-pixel position where mp4v (no quality control) smears motion."""
    writer = cv2.VideoWriter(str(path), cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter.fourcc(*FOURCC),
                             fps, size)
    if not (writer.isOpened() and writer.set(cv2.VIDEOWRITER_PROP_QUALITY, JPEG_QUALITY)):
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


def _png(rgb: np.ndarray) -> bytes:
    ok, data = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return data.tobytes()

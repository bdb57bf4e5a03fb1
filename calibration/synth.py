"""Synthetic recordings of bench tests whose ground truth is known (issue 5).

No real ESTL footage exists yet, so the tracker and the calibration are measured on recordings
made from the bench itself: one level is simulated (`wrapenv.bench.BenchUnit`, after any
levels the unit ran before it, as a lab runs one unit through the EUMOS levels), the sled's
motion is integrated from the pulse, and the side camera films it (`calibration.filming`:
rendered, textured, wrapped, marked with ArUco codes, degraded like a camera). The true poses of
every object the tracker must follow go to `truth.json`.

The recording starts with `pre_roll_s` of the unit standing still, then the pulse (t = pre-roll
is the pulse's start) until the unit rests. World x = sled x + x in the sled frame.
"""

from __future__ import annotations

import fcntl
import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from calibration import opencv_threads, textures
from calibration.camera_setup import (
    DEFAULT_DICTIONARY,
    MarkerPlacement,
    MarkerSpec,
    check_levels_before,
    write_setup,
)
from calibration.filming import Scene, States, drawn_size_m, png, web_alpha, write_video
from calibration.recording import (
    LOAD,
    WRAP,
    Recording,
    SledProfile,
    Truth,
    image_angle_rad,
    write_profile,
    write_truth,
)
from calibration.trajectories import ObjectPath
from wrapenv.bench import BenchUnit, SimSettings
from wrapenv.config import InputError, check_output_folder, write_atomic
from wrapenv.load import PAIRS, Friction, FrictionPair, Layout, LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.render import SideCamera, torn_net
from wrapenv.scene import PALLET_NAME, SLED, SLED_DECK_M, STOPPER, BenchScene
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat

#: The least side (px) at which ArUco finds synth's markers in most frames: on the 2-layer
#: example in Kraft at 0.5 g, 15 px markers were found in 95-97 % of frames, 12 px in 69 %,
#: 7.5-11 px in a ninth to a third (benchmarks/marker_size.py). Below it `synth` warns: `track`
#: then loses the sled's scale check and, on a wrapped unit, the objects it follows only
#: through markers.
MIN_MARKER_PX = 15.0
#: Sled markers this far beyond the pallet's ends (a 1.2 m pallet: x = -1.0 and +1.0 m).
SLED_MARKER_REACH_M = 0.4
#: Empty image border round the whole test, as a fraction of the image's width and height.
MARGIN_FRACTION = 0.04
#: Image sides (px) a recording may have [A]: from 64 (the test is then a few pixels: it is made
#: but nothing in it can be tracked) to a DCI 4K camera's width; beyond, a frame's float buffers
#: (0.2 GB each at 4096 x 4096) run to gigabytes.
SIZE_RANGE_PX = (64, 4096)
#: Lowest frame rate (fps): the video's container (MJPG in AVI, `filming.write_video`) stores
#: none lower; a bench's pulse, a few tenths of a second, is then already between two frames.
MIN_FPS = 1.0
#: Highest frame rate (fps): a high-speed camera's [A] (the source paper filmed at 20 fps);
#: a test's few seconds are then thousands of frames, already an hour to render.
MAX_FPS = 1000.0
#: Longest still pre-roll (s) before the pulse [A].
MAX_PRE_ROLL_S = 10.0
#: A recording is written in a hidden folder `.{name}.XXXX{STAGING_SUFFIX}` beside it, then renamed.
STAGING_SUFFIX = ".synth-partial"
#: The video's file: its container and codec are `filming.write_video`'s.
VIDEO_NAME = "video.avi"


def synthesize(load: LoadUnit, out_dir: str | Path, *, wrap: WrapFormat | None = None,
               level_g: float = 0.4, seed: int = 0, size: tuple[int, int] = (1920, 1200),
               fps: float = 20.0, friction_jitter: float = 0.0, pre_roll_s: float = 0.25,
               stiffness_scale: float = 1.0, tension_scale: float = 1.0,
               marker_size_m: float = 0.06, settings: SimSettings | None = None,
               levels_before_g: tuple[float, ...] = (),
               progress: Callable[[int, int], None] | None = None) -> Recording:
    """Simulate one level of `load` and write its recording folder to `out_dir` (which must not
    exist or be empty). `friction_jitter` draws the true friction of each pair from the load's
    values times U(1 - j, 1 + j) (seeded); the wrap's stiffness and tension are scaled as a
    calibration would find them. The unit first runs `levels_before_g`, unfilmed, as a lab's
    unit runs the levels before the one filmed (setup.toml says which). load.toml and wrap.toml
    hold the load and wrap as given, the truth holds what was simulated; `progress(frame,
    frames)` is called as each frame is written. Returns the recording as `Recording.read`
    reads it."""
    out_dir = Path(out_dir)
    _check_arguments(out_dir, size, fps, friction_jitter, pre_roll_s, marker_size_m,
                     levels_before_g)
    pulse = PulseProfile(level_g)
    friction = _jittered(load.friction, friction_jitter, seed)
    layout = load.with_friction(friction).layout()
    true_wrap = wrap.scaled(stiffness_scale, tension_scale) if wrap is not None else None
    if true_wrap is not None:
        true_wrap.check_fits(layout.load_height_m, "wrap")
    trace = _filmed_level(layout, pulse, settings or SimSettings(), true_wrap, levels_before_g)
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
        "levels_before_g": list(levels_before_g),
        "pallet_slip_m": trace.pallet_slip_m(),
        "size": list(size),
    }
    truth = Truth(params, _tracks(layout, states))
    with _staging(out_dir) as tmp:
        scene = Scene(layout, camera, seed, markers,
                      None if true_wrap is None
                      else (torn_net(true_wrap, layout, trace), web_alpha(true_wrap)))
        # OpenCV split the drawing (warps, blurs of float images) over its threads, and the
        # split changed the rounding: a wrapped take came out 1-2 grey levels apart run to run
        with scene, opencv_threads(0):
            write_video(tmp / VIDEO_NAME, scene.frames(states, progress), fps, size)
            write_atomic(tmp / "template.png", png(scene.template(states)))
        write_profile(tmp, profile)
        write_setup(tmp, fps, camera.px_per_m, camera.origin_px,
                    markers, "template.png", levels_before_g)
        write_atomic(tmp / LOAD, load.to_toml().encode())
        if wrap is not None:
            write_atomic(tmp / WRAP, wrap.to_toml().encode())
        write_truth(tmp, truth)
        try:  # a recording that would not read back is never put in place
            Recording.read(tmp)
        except InputError as exc:  # named where it would have been: tmp is removed
            source = exc.source.replace(str(tmp), str(out_dir), 1)
            raise InputError(source, exc.field, exc.message) from None
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
                     pre_roll_s: float, marker_size_m: float,
                     levels_before_g: tuple[float, ...]) -> None:
    check_output_folder(out_dir, "")
    low, high = SIZE_RANGE_PX
    if not (len(size) == 2 and all(isinstance(v, int) and low <= v <= high for v in size)):
        raise InputError("arguments", "size", f"must be two whole numbers >= {low} and "
                         f"<= {high} (got {size})")
    if not (math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
        raise InputError("arguments", "fps",
                         f"must be >= {MIN_FPS:g} and <= {MAX_FPS:g} (got {fps})")
    if fps != round(fps):
        raise InputError("arguments", "fps", f"must be a whole number: the video's container "
                         f"stores whole frame rates (got {fps:g})")
    if not (math.isfinite(jitter) and 0 <= jitter < 1):
        raise InputError("arguments", "friction_jitter", f"must be in [0, 1) (got {jitter})")
    if not (math.isfinite(pre_roll_s) and 0 <= pre_roll_s <= MAX_PRE_ROLL_S):
        raise InputError("arguments", "pre_roll_s",
                         f"must be >= 0 and <= {MAX_PRE_ROLL_S:g} s (got {pre_roll_s})")
    if not (math.isfinite(marker_size_m) and 0 < marker_size_m <= SLED_DECK_M * 0.75):
        raise InputError("arguments", "marker_size_m",
                         f"must be in (0, {SLED_DECK_M * 0.75:g}] m to fit the sled's side"
                         f" (got {marker_size_m})")
    check_levels_before(levels_before_g,
                        lambda message: InputError("arguments", "levels_before_g", message))


def marker_warning(rec: Recording, size: tuple[int, int]) -> str:
    """Why the markers of this recording, made at `size` (px), are too small for `track` (""
    if they are not), with the size at which they would not be (the camera's scale grows with
    the image's)."""
    if rec.markers is None or rec.markers.size_m is None:
        return ""
    side_px = rec.markers.size_m * rec.px_per_m
    if side_px >= MIN_MARKER_PX:
        return ""
    grow = MIN_MARKER_PX / side_px
    wanted = [16 * math.ceil(side * grow / 16) for side in size]  # whole 16 px codec blocks
    remedy = (f"record at --size {wanted[0]}x{wanted[1]} or larger"
              if max(wanted) <= SIZE_RANGE_PX[1] else
              f"no size up to {SIZE_RANGE_PX[1]} px makes them that large")
    return (f"the markers are {side_px:.1f} px ({rec.markers.size_m:g} m at {rec.px_per_m:g} "
            f"px/m), under the {MIN_MARKER_PX:g} px at which track finds them in most frames; "
            f"{remedy}")


def _jittered(friction: Friction, jitter: float, seed: int) -> Friction:
    """Each pair's static and kinetic coefficients times one factor from U(1 - j, 1 + j), so
    static >= kinetic still holds."""
    rng = np.random.default_rng([seed, 0])
    factors = rng.uniform(1 - jitter, 1 + jitter, len(PAIRS))
    return Friction(**{name: FrictionPair(float(friction.pair(name).static * f),
                                          float(friction.pair(name).kinetic * f))
                       for name, f in zip(PAIRS, factors, strict=True)})


def _filmed_level(layout: Layout, pulse: PulseProfile, settings: SimSettings,
                  wrap: WrapFormat | None, levels_before_g: tuple[float, ...]) -> Trace:
    """The level filmed, on a unit that ran `levels_before_g` first (each to rest)."""
    with BenchUnit(layout, settings, wrap) as unit:
        for level_g in (*levels_before_g, pulse.level_g):
            trace = unit.level(PulseProfile(level_g))
            if not trace.valid:
                raise ValueError(f"the simulation of {level_g:g} g became unphysical "
                                 f"({trace.invalid_reason})")
    return trace


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


def _states(trace: Trace, profile: SledProfile, n_pre: int, fps: float) -> States:
    """Poses at each frame time, interpolated between the trace's samples (rotations
    re-orthonormalised); the unit stands as settled during the pre-roll."""
    frames = n_pre + math.floor(trace.t_s[-1] * fps + 1e-9) + 1
    t = np.arange(frames) / fps
    tau = np.clip(t - n_pre / fps, 0.0, trace.t_s[-1])
    pos = np.concatenate([trace.pallet_pos_m[:, None], trace.bundle_pos_m], axis=1)
    rot = np.concatenate([trace.pallet_rot[:, None], trace.bundle_rot], axis=1)
    x = np.interp(tau, trace.t_s, np.arange(len(trace.t_s)))
    i0 = np.minimum(np.floor(x).astype(int), len(trace.t_s) - 2)
    w = (x - i0)[:, None, None]
    p = (1 - w) * pos[i0] + w * pos[i0 + 1]
    r = (1 - w[..., None]) * rot[i0] + w[..., None] * rot[i0 + 1]
    u, _, vt = np.linalg.svd(r)
    return States(t, p, u @ vt, profile.position_m(t))


def _tracks(layout: Layout, s: States) -> dict[str, ObjectPath]:
    """sled, pallet and the bundles facing the camera (row 1), absolute world coordinates."""
    n = len(s.t_s)
    scene = BenchScene(layout)
    sled = scene.body(SLED)
    tracks = {SLED: ObjectPath(s.t_s, s.sled_x_m.copy(), np.full(n, sled.centre_m[2]),
                                np.zeros(n))}
    for name in [PALLET_NAME] + [b.name for b in layout.bundles if b.name.endswith("R1")]:
        j = scene.state_index(name)
        tracks[name] = ObjectPath(s.t_s, s.sled_x_m + s.pos_m[:, j, 0], s.pos_m[:, j, 2].copy(),
                                   image_angle_rad(s.rot[:, j]))
    return tracks


def _markers(layout: Layout, wrapped: bool, size_m: float) -> MarkerSpec:
    """Two markers on the sled's side, far apart; on a wrapped unit, markers printed on the web
    at the front corners of every layer and of the pallet."""
    px = layout.pallet_size_m[0]
    reach = px / 2 + SLED_MARKER_REACH_M
    placements = [MarkerPlacement(0, SLED, (-reach, 0.0)),
                  MarkerPlacement(1, SLED, (reach, 0.0))]
    if wrapped:
        inset = size_m * (0.5 + textures.QUIET_ZONE) + 0.01
        placements += [MarkerPlacement(2, PALLET_NAME, (-(px / 2 - inset), 0.0)),
                       MarkerPlacement(3, PALLET_NAME, (px / 2 - inset, 0.0))]
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
                         f" {DEFAULT_DICTIONARY} has 50")
    return MarkerSpec(DEFAULT_DICTIONARY, size_m, tuple(placements))


def _fit_camera(layout: Layout, s: States, markers: MarkerSpec, size: tuple[int, int]
                ) -> SideCamera:
    """The largest whole px_per_m at which the whole test fits the image with margins: every
    box at every frame, the stopper and the sled's markers; the origin centres it."""
    scene = BenchScene(layout)
    half = np.array([scene.bodies[w].size_m for w in scene.moving.tolist()]) / 2
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    corners = np.einsum("fbij,bcj->fbci", s.rot, half[:, None] * signs[None]) + s.pos_m[:, :, None]
    xs = [(corners[..., 0] + s.sled_x_m[:, None, None]).ravel()]
    sled = scene.body(SLED)
    zs = [corners[..., 2].ravel(), [sled.centre_m[2] - sled.size_m[2] / 2]]
    reach = drawn_size_m(markers) * (0.5 + textures.QUIET_ZONE)
    for p in markers.placements:
        if p.object == SLED:
            xs.append(s.sled_x_m + p.offset_m[0] - reach)
            xs.append(s.sled_x_m + p.offset_m[0] + reach)
    if layout.pallet_stopper:
        stopper = scene.body(STOPPER)
        xs.append(s.sled_x_m + stopper.centre_m[0] - stopper.size_m[0] / 2)
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

"""The recording folder of a bench test (CONTRACTS.md, "Recording folder"): read, validate, write.

A recording is what the tracker reads and the calibration fits to: the side camera's video, the
sled's profile, the camera mapping and markers (`setup.toml`, read by `camera_setup`), the load
(and wrap) as tested, and for synthetic recordings the true object tracks (`truth.json`). Every
problem with a folder is one `InputError` naming the file and the field, so `wrapbench track` can
exit 2 with one line.

Coordinates: world x along the sled's motion, z up, z = 0 the sled surface; the camera is fixed to
the ground, so world x = sled x + x in the sled frame. Pixels: u = u0 + px_per_m x,
v = v0 - px_per_m z with (u0, v0) = `origin_px`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calibration.camera_setup import SETUP, MarkerSpec, Setup, check_markers, exact
from calibration.trajectories import ObjectPath, Trajectories
from calibration.vision.video import open_video
from wrapenv.config import InputError, read_json, read_toml, write_atomic
from wrapenv.load import LoadUnit
from wrapenv.profile import read_profile_csv
from wrapenv.render import SideCamera
from wrapenv.wrap import WrapFormat

PROFILE, TRUTH = "profile.csv", "truth.json"
LOAD, WRAP = "load.toml", "wrap.toml"
VIDEOS = ("video.mp4", "video.avi")
PROFILE_COLUMNS = ("t_s", "accel_mps2", "vel_mps", "pos_m")
TRACK_KEYS = ("t_s", "x_m", "z_m", "angle_rad")
#: Relative tolerance between setup.toml's fps and the container's (containers store rationals).
FPS_TOLERANCE = 1e-3
#: Slack on time comparisons: the profile may end this much before the last frame's time.
TIME_SLACK_S = 1e-6
#: Slack on a trajectories file's times against the profile: written to microseconds, they
#: may round past a profile that ends `TIME_SLACK_S` early.
TRAJECTORY_SLACK_S = 1e-5
#: The pallet's length on the video, as a share of the frame's width, outside which the
#: camera's scale is a unit slip (pixels per millimetre or centimetre given as per metre):
#: the issue's recordings show it over about a quarter of the frame.
PALLET_SHARE_OF_FRAME = (0.02, 3.0)


@dataclass(frozen=True, eq=False)
class SledProfile:
    """The sled's motion on the recording's time base (t = 0 is the first video frame)."""

    t_s: np.ndarray
    accel_mps2: np.ndarray
    vel_mps: np.ndarray
    pos_m: np.ndarray

    def position_m(self, t: np.ndarray | float) -> np.ndarray:
        """Sled x at times t (s), interpolated; held at the ends."""
        return np.interp(t, self.t_s, self.pos_m)

    @classmethod
    def read(cls, path: str | Path) -> SledProfile:
        columns = read_profile_csv(path, optional=PROFILE_COLUMNS[2:])
        t, a = columns["t_s"], columns["accel_mps2"]
        vel = columns["vel_mps"] if "vel_mps" in columns else _integral(t, a)
        pos = columns["pos_m"] if "pos_m" in columns else _integral(t, vel)
        return cls(t, a, vel, pos)

    def to_csv(self) -> bytes:
        rows = [",".join(PROFILE_COLUMNS)]
        rows += [",".join(exact(v) for v in row) for row in
                 zip(self.t_s, self.accel_mps2, self.vel_mps, self.pos_m, strict=True)]
        return ("\n".join(rows) + "\n").encode()


def _integral(t_s: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The running integral of y over t (trapezoids), 0 at the first sample: the measured
    columns a profile lacks are integrated from the highest derivative it gives."""
    return np.concatenate([[0.0], np.cumsum(np.diff(t_s) * (y[1:] + y[:-1]) / 2)])


@dataclass(frozen=True, eq=False)
class Recording:
    """A validated recording folder."""

    folder: Path
    video: Path                      # video.mp4 or video.avi
    fps: float
    px_per_m: float
    origin_px: tuple[float, float]   # pixel of world x = 0, z = 0 at t = 0
    profile: SledProfile
    load: LoadUnit
    wrap: WrapFormat | None
    markers: MarkerSpec | None
    template: Path | None
    #: The levels (g) the unit ran before this take, in order (setup.toml's
    #: `recording.levels_before_g`); empty: a freshly stacked unit.
    levels_before_g: tuple[float, ...] = ()

    @classmethod
    def read(cls, folder: str | Path) -> Recording:
        """Read and check every file of the folder (the video's container, not its frames)."""
        folder = Path(folder)
        if not folder.is_dir():
            raise InputError(str(folder), "", "not a folder")
        setup_path = folder / SETUP
        setup = Setup.parse(read_toml(setup_path), str(setup_path))
        load = LoadUnit.from_toml(folder / LOAD)
        wrap_path = folder / WRAP
        wrap = (WrapFormat.from_toml(wrap_path, load.layout().load_height_m)
                if wrap_path.exists() else None)
        if setup.markers is not None:
            check_markers(setup.markers, load, str(setup_path))
        template = None
        if setup.template is not None:
            template = folder / setup.template
            if not template.is_file() or cv2.imread(str(template)) is None:
                raise InputError(str(setup_path), setup.template_field,
                                 f"{setup.template} is missing or not an image")
        video = _find_video(folder)
        frames, width_px = _check_video(video, setup.fps, str(setup_path))
        _check_scale(setup.px_per_m, load.pallet.length_m, width_px, str(setup_path))
        profile_path = folder / PROFILE
        profile = SledProfile.read(profile_path)
        _check_covers(profile, (frames - 1) / setup.fps, str(profile_path))
        return cls(folder, video, setup.fps, setup.px_per_m, setup.origin_px, profile, load,
                   wrap, setup.markers, template, setup.levels_before_g)

    def inputs(self) -> tuple[Path, ...]:
        """The folder's files a run reads, which no output may replace."""
        names = (SETUP, PROFILE, LOAD, WRAP, TRUTH)
        return (self.video, *(self.folder / n for n in names),
                *((self.template,) if self.template is not None else ()))

    def camera(self, width: int, height: int) -> SideCamera:
        """The side camera of this recording (`SideCamera.project` gives pixels)."""
        return SideCamera(width, height, self.px_per_m, self.origin_px)

    def check_trajectories(self, tracked: Trajectories, source: str) -> None:
        """Trajectories read from `source` against this recording: objects it has (the sled,
        the pallet, the load's bundles) at times within its profile. A name the load lacks
        would otherwise be dropped unseen (a typo, another load's file), and times in
        milliseconds fitted as seconds."""
        names = {"sled", "pallet"} | {b.name for b in self.load.layout().bundles}
        end_s = float(self.profile.t_s[-1])
        for name, path in tracked.objects.items():
            if name not in names:
                bundles = sorted(names - {"sled", "pallet"})
                raise InputError(source, f"object {name}",
                                 "is not an object of the recording's load.toml (the sled, the "
                                 f"pallet, bundles {bundles[0]} ... {bundles[-1]}): a typo, or "
                                 "another load's file?")
            if path.t_s[0] < -TRAJECTORY_SLACK_S or path.t_s[-1] > end_s + TRAJECTORY_SLACK_S:
                raise InputError(source, f"object {name}: t_s",
                                 f"runs from {path.t_s[0]:g} to {path.t_s[-1]:g} s, outside "
                                 f"profile.csv's 0 to {end_s:g} s (milliseconds? t = 0 is the "
                                 "video's first frame)")


def _find_video(folder: Path) -> Path:
    for name in VIDEOS:
        if (folder / name).is_file():
            return folder / name
    raise InputError(str(folder / VIDEOS[0]), "", f"missing (neither {' nor '.join(VIDEOS)})")


def _check_video(path: Path, fps: float, setup_src: str) -> tuple[int, int]:
    """The number of frames and their width (px), after checking that they decode and run at
    `fps`."""
    cap = open_video(path)
    try:
        ok, frame = cap.read()
        frames = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        container_fps = float(cap.get(cv2.CAP_PROP_FPS))
    finally:
        cap.release()
    if frames < 1:
        raise InputError(str(path), "", "no decodable frame (the container states none)")
    if not ok:
        raise InputError(str(path), "", f"no decodable frame: the first of the {frames} it "
                         "states does not decode (a damaged video?)")
    if not (math.isfinite(container_fps) and container_fps > 0):
        raise InputError(str(path), "", "the container states no frame rate")
    if abs(container_fps - fps) > FPS_TOLERANCE * fps:
        raise InputError(setup_src, "recording.fps", f"{fps} does not match the video's"
                         f" {container_fps:g} fps")
    return frames, int(frame.shape[1])


def _check_scale(px_per_m: float, pallet_m: float, width_px: int, setup_src: str) -> None:
    """The pallet must span a plausible share of the frame at the stated scale."""
    share = px_per_m * pallet_m / width_px
    low, high = PALLET_SHARE_OF_FRAME
    if not low <= share <= high:
        raise InputError(setup_src, "camera.px_per_m",
                         f"at {px_per_m:g} px/m the {pallet_m:g} m pallet spans "
                         f"{px_per_m * pallet_m:.3g} px of the video's {width_px} px: is the "
                         "scale per millimetre or per centimetre? It must be pixels per metre")


def _check_covers(profile: SledProfile, last_frame_s: float, src: str) -> None:
    if profile.t_s[0] > TIME_SLACK_S:
        raise InputError(src, "t_s", f"starts at {profile.t_s[0]:g} s, after the first frame (0 s)")
    if profile.t_s[-1] < last_frame_s - TIME_SLACK_S:
        raise InputError(src, "t_s", f"ends at {profile.t_s[-1]:g} s, before the video's last"
                         f" frame at {last_frame_s:g} s")


def image_angle_rad(rot: np.ndarray) -> np.ndarray:
    """Rotation matrices' angle about the camera axis, counter-clockwise in the image (x right,
    z up): the angle of a track and of truth.json (CONTRACTS.md)."""
    return np.arctan2(rot[..., 2, 0], rot[..., 0, 0])


@dataclass(frozen=True, eq=False)
class Truth:
    """What a synthetic recording really shows: true parameters and object tracks."""

    params: dict
    objects: dict[str, ObjectPath]   # world x, z and `image_angle_rad`, every frame

    @classmethod
    def read(cls, folder: str | Path) -> Truth:
        path = Path(folder) / TRUTH
        src = str(path)
        data = read_json(path)
        params = data.get("params", {})
        if not isinstance(params, dict):
            raise InputError(src, "params", "must be an object")
        objects = data.get("objects")
        if not isinstance(objects, dict) or not objects:
            raise InputError(src, "objects", "must be an object of object tracks")
        return cls(params, {name: _track(item, src, f"objects.{name}")
                            for name, item in objects.items()})

    def to_json(self) -> bytes:
        data = {"params": self.params,
                "objects": {name: {k: [float(v) for v in getattr(track, k)] for k in TRACK_KEYS}
                            for name, track in self.objects.items()}}
        return json.dumps(data, allow_nan=False).encode()


def _track(item: Any, src: str, where: str) -> ObjectPath:
    """One object's track: equally long arrays of finite numbers, at least one sample, times
    strictly increasing (the error against truth interpolates in them)."""
    if not isinstance(item, dict):
        raise InputError(src, where, "must be an object with t_s, x_m, z_m, angle_rad")
    arrays = []
    for key in TRACK_KEYS:
        raw = item.get(key)
        ok = isinstance(raw, list) and all(isinstance(v, int | float) and not isinstance(v, bool)
                                           for v in raw)
        if not ok:
            raise InputError(src, f"{where}.{key}", "must be an array of numbers")
        values = np.array(raw, float)
        if not np.all(np.isfinite(values)):
            raise InputError(src, f"{where}.{key}", "contains NaN or infinite values")
        if len(values) != len(item["t_s"]):
            raise InputError(src, f"{where}.{key}", f"has {len(values)} values, t_s"
                             f" {len(item['t_s'])}")
        arrays.append(values)
    t_s = arrays[0]
    if len(t_s) == 0:
        raise InputError(src, f"{where}.t_s", "needs at least one sample")
    if np.any(np.diff(t_s) <= 0):
        raise InputError(src, f"{where}.t_s", "must increase strictly")
    return ObjectPath(*arrays)


def write_profile(folder: str | Path, profile: SledProfile) -> None:
    write_atomic(Path(folder) / PROFILE, profile.to_csv())


def write_truth(folder: str | Path, truth: Truth) -> None:
    write_atomic(Path(folder) / TRUTH, truth.to_json())

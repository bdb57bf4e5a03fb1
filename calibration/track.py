"""`wrapbench track`: object paths from a bench recording (issue 5, after the source paper).

The pipeline per recording, each step in its own module of `calibration.vision`:
1. the video decoded ahead of the tracker (`video`);
2. a region of interest predicted from the sled profile (`roi`: the unit rides the sled across
   a fixed camera);
3. frame 0: what to follow, named by the layout (`objects`): sled, pallet, and the bundles
   found by template matching; on wrapped units the objects carrying ArUco markers instead
   (`marker_tracks`);
4. every frame: each object followed against its first-frame patch (`tracking`), poses
   converted to world metres with setup.toml's camera, whose scale the sled's markers check
   (`markers`);
5. the paths checked for swapped identities (`checks`), and optionally drawn (`debug_video`).
Bad input raises `InputError`; anything the run could still measure around (lost objects,
missing markers, a short video) is reported in `TrackResult.warnings`, naming the frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from contextlib import AbstractContextManager, closing, nullcontext
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration import opencv_threads
from calibration.camera_setup import MarkerSpec
from calibration.recording import FPS_TOLERANCE, Recording
from calibration.trajectories import ObjectPath, Trajectories
from calibration.vision.checks import frame_ranges, swap_warnings
from calibration.vision.debug_video import DebugVideo
from calibration.vision.marker_tracks import MarkerTracks
from calibration.vision.markers import MarkerDetector, side_px, size_warning
from calibration.vision.objects import (
    TrackedObject,
    View,
    box_size,
    bundles,
    match_template,
    sled_and_pallet,
    sled_marker_centre,
)
from calibration.vision.roi import ROI_MARGIN_M, PixelMap, predict_roi, unit_extent_m
from calibration.vision.tracking import (
    LOST_SCORE,
    OPENCV_TRACKERS,
    Frame,
    MultiTracker,
    Pose,
    Tracker,
    check_tracker,
    make_tracker,
)
from calibration.vision.video import VideoReader
from wrapenv.config import InputError
from wrapenv.scene import SLED_DECK_M

DEFAULT_TRACKER = "ncc+flow"

#: How far the sled's markers may put the sled in frame 0 from where profile.csv's start and
#: setup.toml's camera.origin_px put it: beyond the first a warning, beyond the second the
#: origin is wrong (every absolute position would be as far off) [A]: markers locate to a pixel
#: or two (the synthetic recordings: within 0.2 mm), a pixel clicked as the origin to a few.
ORIGIN_WARN_M, ORIGIN_LIMIT_M = 0.02, 0.05
#: How far the sled followed on the video may depart from profile.csv's path, in metres and as
#: a share of the sled's travel (the larger) [A]: tracking is good to a millimetre, a position
#: integrated from an accelerometer drifts by centimetres; frames lost inside a video, a video
#: rescaled or re-timed, or the sled followed onto something else depart by decimetres to metres.
SLED_PATH_LIMIT_M, SLED_PATH_LIMIT_SHARE = 0.10, 0.05

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class TrackResult:
    trajectories: Trajectories
    warnings: list[str]


def track(recording: Recording, *, tracker: str = DEFAULT_TRACKER,
          debug_video: Path | None = None, progress: Progress | None = None) -> TrackResult:
    """Follow the sled, pallet and visible bundles (or the marker-carrying objects of a wrapped
    unit) through the recording; `progress(frame, frames)` is called after every frame.
    `ValueError` for an unknown tracker (`vision.tracking.check_tracker`)."""
    check_tracker(tracker)
    # objects run in parallel; OpenCV's own threads on small boxes only cost
    with opencv_threads(1), VideoReader(recording.video) as video:
        _check_time_base(recording, video)
        return _Run(recording, tracker, video).go(debug_video, progress)


def _check_time_base(rec: Recording, video: VideoReader) -> None:
    """Frames there are, at setup.toml's rate, all within the profile."""
    if video.stated < 1:
        raise InputError(str(rec.video), "", "no frames")
    if not (math.isfinite(video.fps) and abs(video.fps - rec.fps) <= FPS_TOLERANCE * rec.fps):
        raise InputError(str(rec.folder / "setup.toml"), "recording.fps",
                         f"{rec.fps:g} does not match the video's {video.fps:g} fps")
    end = (video.stated - 1) / rec.fps
    if rec.profile.t_s[-1] < end - 1e-6:
        raise InputError(str(rec.folder / "profile.csv"), "t_s",
                         f"ends at {rec.profile.t_s[-1]:g} s, before the video's last frame at "
                         f"{end:g} s")


def _sled_marker_reach(spec: MarkerSpec | None) -> tuple[float, ...]:
    """x (sled frame) the region of interest must reach for the sled's markers: their centres
    +- a side (half a side and as much again for the quiet zone and blur). A marker of unknown
    size is taken as large as the deck's face, the largest square that fits there."""
    if spec is None:
        return ()
    side = spec.size_m if spec.size_m is not None else SLED_DECK_M
    return tuple(p.offset_m[0] + s * side for p in spec.placements for s in (-1, 1)
                 if p.object == "sled")


def _debug(path: Path | None, fps: float, size: tuple[int, int]
           ) -> AbstractContextManager[DebugVideo | None]:
    """The debug video, whole when the block ends normally and absent when it raises; nothing
    when none was asked for."""
    return DebugVideo(path, fps, size) if path is not None else nullcontext()


def _with_carried(now: dict[str, Pose], markers: MarkerTracks | None,
                  index: int) -> dict[str, Pose]:
    """This frame's poses of the patch-tracked objects and of those carrying markers."""
    return now if markers is None else now | markers.poses_px(index)


class _Poses:
    """Each tracked object's pose in the frames it was found in, and the frames it was lost."""

    def __init__(self, start: dict[str, Pose]) -> None:
        self.found = {name: [(0, pose)] for name, pose in start.items()}
        self.lost: dict[str, list[int]] = {name: [] for name in start}

    def record(self, index: int, results: dict[str, tuple[Pose, float]]) -> dict[str, Pose]:
        """Keep this frame's results; the poses found."""
        now = {}
        for name in self.found:
            pose, score = results[name]
            if score < LOST_SCORE:
                self.lost[name].append(index)
            else:
                self.found[name].append((index, pose))
                now[name] = pose
        return now

    def latest(self) -> dict[str, Pose]:
        return {name: poses[-1][1] for name, poses in self.found.items()}

    def drop_lone_finds(self) -> None:
        """A single frame found between lost ones is lost too: a falling bundle the patch
        tracker loses can score one frame above `LOST_SCORE` on whatever it lands on (a
        recorded take: one frame 284 mm off, written without a word)."""
        for name, poses in self.found.items():
            lost = set(self.lost[name])
            lone = {i for i, _ in poses if i - 1 in lost and i + 1 in lost}
            if lone:
                self.found[name] = [(i, pose) for i, pose in poses if i not in lone]
                self.lost[name] = sorted(lost | lone)

    def warnings(self) -> list[str]:
        return [f"{name}: lost (NCC < {LOST_SCORE}) in frames {frame_ranges(frames)}; those "
                "frames are left out" for name, frames in self.lost.items() if frames]

    def paths(self, pixmap: PixelMap, fps: float) -> dict[str, ObjectPath]:
        out = {}
        for name, poses in self.found.items():
            k = np.array([i for i, _ in poses])
            x, z = pixmap.to_world(np.array([p.u for _, p in poses]),
                                   np.array([p.v for _, p in poses]))
            out[name] = ObjectPath(k / fps, x, z, np.array([p.theta for _, p in poses]))
        return out


class _Run:
    """One recording tracked: frame 0 names the objects and starts their trackers, every later
    frame moves them."""

    def __init__(self, recording: Recording, tracker: str, video: VideoReader) -> None:
        self.rec, self.kind, self.video = recording, tracker, video
        self.warnings: list[str] = []
        self.out_of_view: list[int] = []
        self.pixmap = PixelMap(recording.px_per_m, *recording.origin_px)
        self.layout = recording.load.layout()
        self.sled_x = recording.profile.position_m(np.arange(video.stated) / recording.fps)
        self.view = View(self.layout, self.pixmap, video.size, float(self.sled_x[0]))
        self.full_frame = tracker in OPENCV_TRACKERS
        spec = recording.markers
        self.detector = (MarkerDetector(spec.dictionary) if spec and spec.placements else None)
        #: objects followed through their markers: the load's, when the web hides it
        self.carriers = ({p.object for p in spec.placements if p.object != "sled"}
                         if spec and recording.wrap is not None else set())
        self.roi_extent = unit_extent_m(self.layout, _sled_marker_reach(spec))

    def frame(self, index: int, bgr: np.ndarray) -> Frame | None:
        """Grayscale of the frame's region of interest (the whole frame for OpenCV's trackers);
        None when that region lies wholly outside the image: the unit is out of view."""
        box = predict_roi(self.pixmap, self.roi_extent, self.sled_at(index), self.video.size,
                          ROI_MARGIN_M)
        if box.empty:
            return None
        if self.full_frame:
            return Frame(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
        crop = bgr[box.y0:box.y1, box.x0:box.x1]
        return Frame(cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY), box.x0, box.y0)

    def first_frame(self, bgr: np.ndarray) -> Frame:
        """Frame 0's region of interest; the unit must be in view there, or setup.toml's
        camera (or the profile's start) is wrong and nothing could be named."""
        first = self.frame(0, bgr)
        if first is None:
            width, height = self.video.size
            raise InputError(str(self.rec.folder / "setup.toml"), "camera.origin_px",
                             f"{list(self.rec.origin_px)} puts the unit (sled at "
                             f"x = {self.sled_x[0]:g} m by profile.csv) outside the "
                             f"{width}x{height} image in frame 0")
        return first

    def sled_at(self, index: int) -> float:
        """The sled's x in frame `index` according to the profile."""
        if index >= len(self.sled_x):  # more frames than the container stated
            self.sled_x = self.rec.profile.position_m(np.arange(index + 1) / self.rec.fps)
        return float(self.sled_x[index])

    def go(self, debug_video: Path | None, progress: Progress | None) -> TrackResult:
        frames = self.video.frames()
        bgr = next(frames, None)
        if bgr is None:
            raise InputError(str(self.rec.video), "", "no whole frame decodes" if
                             self.video.truncated else "the first frame does not decode")
        first = self.first_frame(bgr)
        found = self.detector.detect(first) if self.detector is not None else {}
        self._check_marker_size(found)
        objects = self._objects(first, found)
        trackers = self._trackers(first, [o for o in objects if o.name not in self.carriers])
        if not trackers and not self.carriers:
            raise InputError(str(self.rec.video), "", "no object can be followed from frame 0 "
                             f"({self.warnings[-1] if self.warnings else 'none found'})")
        poses = _Poses({o.name: Pose(*o.centre_px) for o in objects if o.name in trackers})
        drawn = objects + self._carried(objects)
        with closing(MultiTracker(trackers, poses.latest())) as multi, \
                _debug(debug_video, self.rec.fps, self.video.size) as debug:
            markers = self._marker_tracks(multi)
            if markers is not None:
                markers.start(first, found, 0.0)
            if debug is not None:
                debug.draw(bgr, 0, drawn, _with_carried(poses.latest(), markers, 0))
            if progress:
                progress(1, self.video.stated)
            index = 0
            for index, bgr in enumerate(frames, start=1):
                now = self._step(index, bgr, multi, markers, poses)
                if debug is not None:
                    debug.draw(bgr, index, drawn, _with_carried(now, markers, index))
                if progress:
                    progress(index + 1, self.video.stated)
            # inside the block: a recording refused by the result's checks leaves no video
            return self._result(objects, poses, markers, index + 1)

    def _step(self, index: int, bgr: np.ndarray, multi: MultiTracker,
              markers: MarkerTracks | None, poses: _Poses) -> dict[str, Pose]:
        """Move every object into frame `index`; the poses found (none while the unit is out
        of view: every object is then lost, the frame noted for one warning)."""
        frame = self.frame(index, bgr)
        if frame is None:
            self.out_of_view.append(index)
            return {}
        sled_u = self.pixmap.px_per_m * (self.sled_at(index) - self.sled_x[0])
        results = multi.step(frame, sled_u)
        if markers is not None:
            markers.step(index, frame, sled_u, results)
        return poses.record(index, results)

    def _result(self, objects: list[TrackedObject], poses: _Poses,
                markers: MarkerTracks | None, frames: int) -> TrackResult:
        if self.video.truncated:
            self.warnings.append(f"{self.rec.video.name}: the container states "
                                 f"{self.video.stated} frames, only {self.video.decoded} decode "
                                 "(a truncated file?) and the last may be cut short: dropped; "
                                 f"tracked frames 0-{frames - 1}")
        if self.out_of_view:
            self.warnings.append(f"unit out of view in frames {frame_ranges(self.out_of_view)}"
                                 ": its predicted region is outside the image (profile.csv's "
                                 "pos_m or setup.toml's camera); no object tracked there")
        poses.drop_lone_finds()
        self.warnings += poses.warnings()
        paths = poses.paths(self.pixmap, self.rec.fps)
        self._check_sled_path(paths)
        if markers is not None:
            paths.update(markers.paths(frames, self.rec.fps))
        half = {o.name: 0.5 * min(o.size_px) / self.pixmap.px_per_m for o in objects}
        self.warnings += swap_warnings(paths, half, self.rec.fps)
        return TrackResult(Trajectories(paths), self.warnings)

    def _objects(self, first: Frame, found: dict[int, np.ndarray]) -> list[TrackedObject]:
        """Sled, pallet and front-row bundles with their first-frame centres and box sizes;
        `found`: the markers ArUco sees in the first frame."""
        sled_x0 = self.view.sled_x0_m
        spec = self.rec.markers
        if self.detector is not None and spec is not None:
            sled = {p.id: p.offset_m for p in spec.placements if p.object == "sled"}
            centre = sled_marker_centre(self.view, found, sled, self.warnings)
            if centre is not None:
                self._check_origin(*centre)
                sled_x0 = centre[0]
        objects = sled_and_pallet(self.view, sled_x0)
        if self.rec.wrap is None:
            matches = (match_template(self.view, first, self.rec.template)
                       if self.rec.template else None)
            objects += bundles(self.view, matches, self.warnings)
        elif not self.carriers & {b.name for b in self.layout.bundles}:
            self.warnings.append("the layers of a wrapped unit are followed only through "
                                 "markers, and setup.toml places none on its bundles: no "
                                 "layer is tracked")
        return objects

    def _check_origin(self, x_m: float, z_m: float) -> None:
        """The sled's centre by its markers against where profile.csv's start and
        camera.origin_px put it in frame 0; the origin that would agree is named."""
        dx = x_m - self.view.sled_x0_m
        dz = z_m + SLED_DECK_M / 2
        if math.hypot(dx, dz) <= ORIGIN_WARN_M:
            return
        (u0, v0), s = self.rec.origin_px, self.pixmap.px_per_m
        text = (f"the sled's markers put the sled {1000 * dx:+.0f} mm along x and "
                f"{1000 * dz:+.0f} mm along z from where profile.csv's start and camera.origin_px "
                f"{list(self.rec.origin_px)} put it in frame 0; origin_px = "
                f"[{u0 + s * dx:.0f}, {v0 - s * dz:.0f}] would agree (or the markers' offset_m "
                "are wrong)")
        if math.hypot(dx, dz) > ORIGIN_LIMIT_M:
            raise InputError(str(self.rec.folder / "setup.toml"), "camera.origin_px", text)
        self.warnings.append(text)

    def _check_sled_path(self, paths: dict[str, ObjectPath]) -> None:
        """The sled followed on the video against profile.csv's path from the same start: they
        part when frames are lost inside the video (every later frame is then stamped too
        early), when the video was rescaled or re-timed, or the camera's scale is wrong."""
        sled = paths.get("sled")
        if sled is None or len(sled.t_s) < 2:
            return
        pos = self.rec.profile.position_m(sled.t_s)
        departure = np.abs((sled.x_m - sled.x_m[0]) - (pos - pos[0]))
        limit = max(SLED_PATH_LIMIT_M, SLED_PATH_LIMIT_SHARE * float(np.ptp(pos)))
        if departure.max() <= limit:
            return
        k = int(np.argmax(departure > limit))
        lost = (f" (it decodes {self.video.decoded} of the {self.video.stated} frames its "
                "container states)" if self.video.truncated else "")
        raise InputError(str(self.rec.video), "frames",
                         f"the sled followed on the video departs from profile.csv's path by "
                         f"{1000 * departure[k]:.0f} mm from t = {sled.t_s[k]:.2f} s (up to "
                         f"{1000 * departure.max():.0f} mm): frames lost or re-timed inside the "
                         f"video{lost}, a rescaled video, or setup.toml's camera.px_per_m or "
                         "profile.csv's pos_m wrong")

    def _check_marker_size(self, found: dict[int, np.ndarray]) -> None:
        """markers.size_m against the sides of the placed markers ArUco finds in frame 0."""
        spec = self.rec.markers
        if self.detector is None or spec is None:
            return
        placed = {p.id for p in spec.placements}
        sides = [side_px(corners) for i, corners in found.items() if i in placed]
        if warning := size_warning(spec.size_m, self.pixmap.px_per_m, sides):
            self.warnings.append(warning)

    def _carried(self, objects: list[TrackedObject]) -> list[TrackedObject]:
        """The bundles followed through their markers (not among `objects`), with their
        outlines' boxes at rest, for the debug video."""
        s, named = self.pixmap.px_per_m, {o.name for o in objects}
        out = []
        for b in self.layout.bundles:
            if b.name in self.carriers and b.name not in named:
                u, v = self.pixmap.to_px(b.centre_m[0] + self.view.sled_x0_m, b.centre_m[2])
                out.append(TrackedObject(b.name, (float(u), float(v)),
                                         box_size(s * b.size_m[0], s * b.size_m[2])))
        return out

    def _trackers(self, first: Frame, objects: list[TrackedObject]) -> dict[str, Tracker]:
        trackers = {}
        for o in objects:
            try:
                trackers[o.name] = make_tracker(self.kind, first, o.centre_px, o.size_px)
            except ValueError as exc:
                self.warnings.append(f"{o.name}: cannot be followed from frame 0 ({exc}); "
                                     "not tracked")
        return trackers

    def _marker_tracks(self, multi: MultiTracker) -> MarkerTracks | None:
        """The carried markers' tracks, on a wrapped unit with markers on its objects."""
        spec = self.rec.markers
        if self.detector is None or spec is None or not self.carriers:
            return None
        side = None if spec.size_m is None else spec.size_m * self.pixmap.px_per_m
        placements = [p for p in spec.placements if p.object in self.carriers]
        return MarkerTracks(placements, side, self.detector, multi, self.pixmap, self.warnings)

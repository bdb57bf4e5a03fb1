"""`wrapbench track`: object paths from a bench recording (issue 5, after the source paper).

The pipeline per recording:
1. region of interest from the sled profile (the unit rides the sled across a fixed camera);
2. first frame: the bundles by template matching (NCC + NMS) inside it, named by the layout
   position nearest to each match (`L{layer}C{column}R1`); pallet and sled from the layout;
   on wrapped units the bundles are hidden, so ArUco names the objects carrying markers and the
   patch tracker follows a box round each marker (marker, quiet zone and a little web): an
   18 px marker's ArUco corners give a noisy pose and are missed in some frames, the patch
   fitted to the first frame's is sub-pixel; the object's centre is the marker's minus its
   placement offset turned by the tracked rotation;
3. every frame: each object followed against its first-frame patch (`vision.tracking`), poses
   converted to world metres with setup.toml's camera, whose scale the sled's markers check.
   ArUco runs again only every `MARKER_CHECK_EVERY` frames and where a marker was lost or not
   yet seen: to cross-check the patch tracker, re-acquire lost markers and start late ones.
Bad input raises `InputError`; anything the run could still measure around (lost objects,
missing markers, a short video) is reported in `TrackResult.warnings`, naming the frames.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.recording import MarkerPlacement, Recording
from calibration.trajectories import ObjectPath, Trajectories
from calibration.vision.detection import Detection, find_template
from calibration.vision.markers import (
    MarkerDetector,
    angle_rad,
    baseline_scale,
    centre_px,
    object_pose,
    rigid_pose,
    scale_warning,
)
from calibration.vision.roi import PixelMap, predict_roi, unit_extent_m
from calibration.vision.tracking import (
    LOST_SCORE,
    OPENCV_TRACKERS,
    Frame,
    MultiTracker,
    PatchTracker,
    Pose,
    Tracker,
    make_tracker,
)
from wrapenv.bench import SLED_DECK_M
from wrapenv.config import InputError
from wrapenv.load import Layout

DEFAULT_TRACKER = "ncc+flow"
#: A template match must score this much (TM_CCOEFF_NORMED) to count as a bundle.
MATCH_THRESHOLD = 0.6
#: Margin of the region of interest around the unit: bundles slide and tip within it.
ROI_MARGIN_M = 0.25
#: Inset of an object's tracked box from its outline, so no neighbour is in its reference patch.
INSET_M = 0.012
#: A match farther than this fraction of the bundle's size from every layout position is ignored.
MATCH_RADIUS = 0.35
#: Container and setup frame rates may differ by this fraction.
FPS_TOLERANCE = 1e-3
#: Side of a marker's tracked box in marker sides: the printed square, its white border (at
#: least one of a 4x4 code's six modules) and a little web.
MARKER_BOX_SIDES = 1.6
#: ArUco cross-checks the marker trackers every this many frames.
MARKER_CHECK_EVERY = 10
#: Tracked and detected marker centres further apart than this (px) are reported.
MARKER_CHECK_PX = 1.5


@dataclass(frozen=True)
class TrackResult:
    trajectories: Trajectories
    warnings: list[str]


@dataclass(frozen=True)
class _Object:
    name: str
    centre_px: tuple[float, float]
    size_px: tuple[int, int]


def track(recording: Recording, *, tracker: str = DEFAULT_TRACKER,
          debug_video: Path | None = None,
          progress: Callable[[int, int], None] | None = None) -> TrackResult:
    """Follow the sled, pallet and visible bundles (or the marker-carrying objects of a wrapped
    unit) through the recording; `progress(frame, frames)` is called after every frame."""
    run = _Run(recording, tracker)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # objects run in parallel; OpenCV's own threads on small boxes only cost
    try:
        return run.go(debug_video, progress)
    finally:
        cv2.setNumThreads(threads)
        run.close()


class _Run:
    def __init__(self, recording: Recording, tracker: str) -> None:
        self.rec, self.kind = recording, tracker
        self.warnings: list[str] = []
        self.cap = cv2.VideoCapture(str(recording.video))
        if not self.cap.isOpened():
            raise InputError(str(recording.video), "", "cannot open the video")
        self.frames = int(self.cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self._check_time_base()
        self.size = (int(self.cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
                     int(self.cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        self.pixmap = PixelMap(recording.px_per_m, *recording.origin_px)
        self.layout = recording.load.layout()
        times = np.arange(max(self.frames, 1)) / recording.fps
        self.sled_x = recording.profile.position_m(times)
        self.full_frame = tracker in OPENCV_TRACKERS
        self.markers = (MarkerDetector(recording.markers.dictionary)
                        if recording.markers and recording.markers.placements else None)
        #: markers are looked for in every frame only where they carry objects (wrapped units)
        self.follow_markers = self.markers is not None and bool(self._marker_objects())
        self.writer: cv2.VideoWriter | None = None
        spec = recording.markers
        #: the sled's markers, which the region of interest must reach (centre +- half a side)
        sled_marker_x = tuple(p.offset_m[0] + s * spec.size_m for p in spec.placements
                              for s in (-1, 1) if p.object == "sled") if spec else ()
        self.roi_extent = unit_extent_m(self.layout, sled_marker_x)

    def _check_time_base(self) -> None:
        video, fps = self.rec.video, float(self.cap.get(cv2.CAP_PROP_FPS))
        if self.frames < 1:
            raise InputError(str(video), "", "no frames")
        if not (math.isfinite(fps) and abs(fps - self.rec.fps) <= FPS_TOLERANCE * self.rec.fps):
            raise InputError(str(self.rec.folder / "setup.toml"), "recording.fps",
                             f"{self.rec.fps:g} does not match the video's {fps:g} fps")
        end = (self.frames - 1) / self.rec.fps
        if self.rec.profile.t_s[-1] < end - 1e-6:
            raise InputError(str(self.rec.folder / "profile.csv"), "t_s",
                             f"ends at {self.rec.profile.t_s[-1]:g} s, before the video's last "
                             f"frame at {end:g} s")

    def close(self) -> None:
        self.cap.release()
        if self.writer is not None:
            self.writer.release()

    def frame(self, index: int, bgr: np.ndarray) -> Frame:
        """Grayscale of the frame's region of interest (the whole frame for OpenCV's trackers)."""
        if self.full_frame:
            return Frame(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))
        box = predict_roi(self.pixmap, self.roi_extent, self.sled_x[index], self.size,
                          ROI_MARGIN_M)
        crop = bgr[box.y0:box.y1, box.x0:box.x1]
        return Frame(cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY), box.x0, box.y0)

    def go(self, debug_video: Path | None,
           progress: Callable[[int, int], None] | None) -> TrackResult:
        ok, bgr = self.cap.read()
        if not ok:
            raise InputError(str(self.rec.video), "", "the first frame does not decode")
        first = self.frame(0, bgr)
        found = self.markers.detect(first) if self.markers is not None else {}
        objects = self._objects(first, found)
        trackers = self._trackers(first, [o for o in objects
                                          if o.name not in self._marker_objects()])
        tracked = [o for o in objects if o.name in trackers]
        multi = MultiTracker(trackers, {o.name: Pose(*o.centre_px) for o in tracked})
        poses: dict[str, list[tuple[int, Pose]]] = {o.name: [(0, Pose(*o.centre_px))]
                                                    for o in tracked}
        lost: dict[str, list[int]] = {o.name: [] for o in tracked}
        markers = _MarkerTracks(self, multi) if self.follow_markers else None
        if markers is not None:
            markers.start(first, found, 0.0)
        if debug_video is not None:
            self._open_writer(debug_video)
            self._draw(bgr, 0, objects, {n: p[-1][1] for n, p in poses.items()})
        index = 0
        if progress:
            progress(1, self.frames)
        try:
            for bgr in self._decoded():
                index += 1
                if index >= len(self.sled_x):
                    self.sled_x = self.rec.profile.position_m(np.arange(index + 1) / self.rec.fps)
                frame = self.frame(index, bgr)
                sled_u = self.pixmap.px_per_m * (self.sled_x[index] - self.sled_x[0])
                results = multi.step(frame, sled_u)
                if markers is not None:
                    markers.step(index, frame, sled_u, results)
                now = {}
                for name in poses:
                    pose, score = results[name]
                    if score < LOST_SCORE:
                        lost[name].append(index)
                    else:
                        poses[name].append((index, pose))
                        now[name] = pose
                if self.writer is not None:
                    self._draw(bgr, index, objects, now)
                if progress:
                    progress(index + 1, self.frames)
        finally:
            multi.close()
        if index + 1 < self.frames:
            self.warnings.append(f"{self.rec.video.name}: the container states {self.frames} "
                                 f"frames, only {index + 1} decode; tracked those")
        for name, frames in lost.items():
            if frames:
                self.warnings.append(f"{name}: lost (NCC < {LOST_SCORE}) in frames "
                                     f"{_ranges(frames)}; those frames are left out")
        paths = {name: self._path(p) for name, p in poses.items()}
        if markers is not None:
            paths.update(markers.paths(index + 1))
        self._check_swaps(paths, objects)
        return TrackResult(Trajectories(paths), self.warnings)

    def _decoded(self) -> Iterator[np.ndarray]:
        """The remaining frames; the next one decodes on another thread while the caller
        tracks this one (OpenCV releases the GIL: decoding is a fifth of the time per frame)."""
        with ThreadPoolExecutor(1) as reader:
            pending = reader.submit(self.cap.read)
            while True:
                ok, bgr = pending.result()
                if not ok:
                    return
                pending = reader.submit(self.cap.read)
                yield bgr

    def _trackers(self, first: Frame, objects: list[_Object]) -> dict[str, Tracker]:
        trackers = {}
        for o in objects:
            try:
                trackers[o.name] = make_tracker(self.kind, first, o.centre_px, o.size_px)
            except ValueError as exc:
                self.warnings.append(f"{o.name}: cannot be followed from frame 0 ({exc}); "
                                     "not tracked")
        return trackers

    # -- first frame -------------------------------------------------------------------------

    def _objects(self, first: Frame, found: dict[int, np.ndarray]) -> list[_Object]:
        """Sled, pallet and front-row bundles with their first-frame centres and box sizes;
        `found`: the markers ArUco sees in the first frame."""
        s, x0 = self.pixmap.px_per_m, self.sled_x[0]
        inset = 2 * INSET_M
        px, _, pz = self.layout.pallet_size_m
        sled_x0 = self._sled_start(found)
        objects = [
            _Object("sled", tuple(self.pixmap.to_px(sled_x0, -SLED_DECK_M / 2)),
                    _size(s * (px + 0.2), s * (SLED_DECK_M - inset))),
            _Object("pallet", tuple(self.pixmap.to_px(x0, pz / 2)),
                    _size(s * (px - inset), s * (pz - inset))),
        ]
        if self.rec.wrap is None:
            objects += self._bundles(first)
        return objects

    def _sled_start(self, found: dict[int, np.ndarray]) -> float:
        """The sled's x at the first frame: from its markers when they are seen, else the
        profile's (and the distance between them checks setup.toml's scale either way)."""
        spec = self.rec.markers
        if self.markers is None or spec is None:
            return float(self.sled_x[0])
        sled = {p.id: p.offset_m for p in spec.placements if p.object == "sled"}
        scale = scale_warning(baseline_scale(found, sled), self.pixmap.px_per_m)
        if scale:
            self.warnings.append(scale)
        seen = [(found[i], offset) for i, offset in sled.items() if i in found]
        if not seen:
            self.warnings.append("sled markers not found in frame 0: the sled starts where "
                                 "profile.csv puts it")
            return float(self.sled_x[0])
        return object_pose(seen, self.pixmap).x_m

    def _bundles(self, first: Frame) -> list[_Object]:
        """Front-row bundles: template matches named after the nearest layout position; a
        position no match comes near is started from the layout, with a warning."""
        expected = _front_row(self.layout)
        s, x0 = self.pixmap.px_per_m, self.sled_x[0]
        inset = 2 * INSET_M
        found = self._match_template(first) if self.rec.template else []
        objects = []
        for name, (bx, bz, length, height) in expected.items():
            u, v = self.pixmap.to_px(bx + x0, bz)
            radius = MATCH_RADIUS * s * min(length, height)
            near = [d for d in found if math.hypot(d.u - u, d.v - v) < radius]
            if near:
                best = max(near, key=lambda d: d.score)
                u, v = best.u, best.v
            elif self.rec.template:
                self.warnings.append(f"{name}: no template match near its layout position in "
                                     "frame 0; started from the layout")
            objects.append(_Object(name, (float(u), float(v)),
                                   _size(s * (length - inset), s * (height - inset))))
        return objects

    def _match_template(self, first: Frame) -> list[Detection]:
        path = self.rec.template
        assert path is not None
        template = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if template is None:
            raise InputError(str(path), "", "cannot read the template image")
        box = predict_roi(self.pixmap, unit_extent_m(self.layout), self.sled_x[0], self.size,
                          ROI_MARGIN_M)
        roi = first.gray[box.y0 - first.y0:box.y1 - first.y0, box.x0 - first.x0:box.x1 - first.x0]
        found = find_template(roi, template, MATCH_THRESHOLD)
        if not found:
            raise InputError(str(path), "", f"no match scoring >= {MATCH_THRESHOLD} in the first "
                             "frame's region of interest: is it a bundle's front face at the "
                             "recording's scale?")
        return [Detection(d.u + box.x0, d.v + box.y0, d.score, d.width, d.height) for d in found]

    # -- markers -----------------------------------------------------------------------------

    def _marker_objects(self) -> set[str]:
        """Objects followed through their markers: the load's, when the web hides it."""
        spec = self.rec.markers
        if spec is None or self.rec.wrap is None:
            return set()
        return {p.object for p in spec.placements if p.object != "sled"}

    # -- results -----------------------------------------------------------------------------

    def _path(self, poses: list[tuple[int, Pose]]) -> ObjectPath:
        k = np.array([i for i, _ in poses])
        u = np.array([p.u for _, p in poses])
        v = np.array([p.v for _, p in poses])
        x, z = self.pixmap.to_world(u, v)
        return ObjectPath(k / self.rec.fps, x, z, np.array([p.theta for _, p in poses]))

    def _check_swaps(self, paths: dict[str, ObjectPath], objects: list[_Object]) -> None:
        """Warn when two objects' centres come closer than half a box: one tracker may have
        jumped to its neighbour."""
        half = {o.name: 0.5 * min(o.size_px) / self.pixmap.px_per_m for o in objects}
        names = [n for n in paths if n in half]
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                pa, pb = paths[a], paths[b]
                common, ia, ib = np.intersect1d(pa.t_s, pb.t_s, return_indices=True)
                if common.size == 0:
                    continue
                d = np.hypot(pa.x_m[ia] - pb.x_m[ib], pa.z_m[ia] - pb.z_m[ib])
                close = d < min(half[a], half[b])
                if np.any(close):
                    frames = np.rint(common[close] * self.rec.fps).astype(int).tolist()
                    self.warnings.append(f"{a} and {b} overlap in frames {_ranges(frames)}: "
                                         "their identities may have swapped")

    # -- debug video -------------------------------------------------------------------------

    def _open_writer(self, path: Path) -> None:
        self.writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"mp4v"), self.rec.fps,
                                      self.size)
        if not self.writer.isOpened():
            raise InputError(str(path), "", "cannot write the debug video there")

    def _draw(self, bgr: np.ndarray, index: int, objects: list[_Object],
              poses: dict[str, Pose]) -> None:
        """Rotated box, centre dot and name of every object found in this frame."""
        assert self.writer is not None
        image = bgr.copy()
        for obj in objects:
            pose = poses.get(obj.name)
            if pose is None:
                continue
            rect = ((pose.u, pose.v), obj.size_px, -math.degrees(pose.theta))
            corners = np.round(cv2.boxPoints(rect)).astype(np.int32)
            cv2.polylines(image, [corners], True, (0, 255, 255), 1, cv2.LINE_AA)
            centre = (int(round(pose.u)), int(round(pose.v)))
            cv2.circle(image, centre, 3, (0, 0, 255), -1, cv2.LINE_AA)
            cv2.putText(image, obj.name, (centre[0] + 5, centre[1] - 5),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 255, 255), 1, cv2.LINE_AA)
        cv2.putText(image, f"frame {index}", (10, 25), cv2.FONT_HERSHEY_SIMPLEX, 0.7,
                    (255, 255, 255), 2, cv2.LINE_AA)
        self.writer.write(image)


class _MarkerTracks:
    """The markers of a wrapped unit's objects, each followed by a patch tracker on its box
    from the frame ArUco first sees it in; ArUco runs again only to cross-check, re-acquire
    and start (see the module docstring)."""

    def __init__(self, run: _Run, multi: MultiTracker) -> None:
        spec = run.rec.markers
        assert spec is not None and run.markers is not None
        self.run, self.multi, self.detector = run, multi, run.markers
        carriers = run._marker_objects()
        self.placements: dict[int, MarkerPlacement] = {p.id: p for p in spec.placements
                                                       if p.object in carriers}
        side = MARKER_BOX_SIDES * spec.size_m * run.pixmap.px_per_m
        self.box = _size(side, side)
        #: the object's rotation in the frame its marker was first seen (0 at rest, frame 0)
        self.theta0: dict[int, float] = {}
        self.poses: dict[int, dict[int, Pose]] = {}
        self.lost: dict[int, list[int]] = {}
        self.disagree: dict[int, list[int]] = {}
        self.unusable: set[int] = set()

    def start(self, frame: Frame, found: dict[int, np.ndarray], sled_u: float,
              index: int = 0) -> None:
        """Trackers for the carried markers in `found` that have none yet."""
        for i, corners in found.items():
            placement = self.placements.get(i)
            if placement is None or i in self.theta0 or i in self.unusable:
                continue
            centre = centre_px(corners)
            try:
                tracker = PatchTracker(frame, (float(centre[0]), float(centre[1])), self.box)
            except ValueError as exc:
                self.unusable.add(i)
                self.run.warnings.append(f"marker {i} ({placement.object}): cannot be followed "
                                         f"from frame {index} ({exc})")
                continue
            self.theta0[i] = self._object_theta(placement.object, index, corners)
            pose = Pose(float(centre[0]), float(centre[1]))
            self.multi.add(_marker_name(i), tracker, pose, sled_u)
            self.poses[i], self.lost[i], self.disagree[i] = {index: pose}, [], []

    def _object_theta(self, name: str, index: int, corners: np.ndarray) -> float:
        """The object's rotation now: zero in frame 0 (at rest, as placements are given), else
        from another of its markers followed in this frame, else the marker's own edges."""
        if index == 0:
            return 0.0
        for i, poses in self.poses.items():
            if self.placements[i].object == name and index in poses:
                return poses[index].theta + self.theta0[i]
        return angle_rad(corners)

    def step(self, index: int, frame: Frame, sled_u: float,
             results: dict[str, tuple[Pose, float]]) -> None:
        """Record this frame's marker poses; ArUco on check frames, and where a marker was
        lost or has not been seen yet."""
        lost = {i for i in self.theta0 if results[_marker_name(i)][1] < LOST_SCORE}
        unseen = set(self.placements) - set(self.theta0) - self.unusable
        if lost or unseen or index % MARKER_CHECK_EVERY == 0:
            found = self.detector.detect(frame)
            for i in lost & set(found):
                u, v = centre_px(found[i])
                predicted = Pose(float(u), float(v), results[_marker_name(i)][0].theta)
                results[_marker_name(i)] = self.multi.retry(_marker_name(i), frame, predicted)
            for i in set(self.theta0) & set(found):
                pose, score = results[_marker_name(i)]
                if score >= LOST_SCORE and math.dist((pose.u, pose.v),
                                                     centre_px(found[i])) > MARKER_CHECK_PX:
                    self.disagree[i].append(index)
            known = set(self.theta0)
            self._record(index, known, results)
            self.start(frame, {i: c for i, c in found.items() if i in unseen}, sled_u, index)
        else:
            self._record(index, set(self.theta0), results)

    def _record(self, index: int, ids: set[int], results: dict[str, tuple[Pose, float]]) -> None:
        for i in ids:
            pose, score = results[_marker_name(i)]
            if score < LOST_SCORE:
                self.lost[i].append(index)
            else:
                self.poses[i][index] = pose

    def paths(self, frames: int) -> dict[str, ObjectPath]:
        """Per carrying object, its pose in every frame one of its markers is followed in; gaps
        inside the run are interpolated, frames outside it left out, and both reported."""
        out = {}
        for name in sorted({p.object for p in self.placements.values()}):
            ids = sorted(i for i, p in self.placements.items() if p.object == name)
            self._warn_markers(name, ids)
            ks, values = [], []
            for k in range(frames):
                seen = [i for i in ids if k in self.poses.get(i, {})]
                if seen:
                    ks.append(k)
                    values.append(self._pose(k, seen))
            if not ks:
                self.run.warnings.append(f"{name}: markers {ids} never detected; not tracked")
                continue
            self._warn_gaps(name, ks, frames)
            span = np.arange(ks[0], ks[-1] + 1)
            vals = np.array(values)
            x, z, a = (np.interp(span, ks, vals[:, j]) for j in range(3))
            out[name] = ObjectPath(span / self.run.rec.fps, x, z, a)
        return out

    def _pose(self, k: int, ids: list[int]) -> tuple[float, float, float]:
        poses = [self.poses[i][k] for i in ids]
        thetas = np.array([p.theta + self.theta0[i] for p, i in zip(poses, ids, strict=True)])
        theta = float(np.arctan2(np.sin(thetas).mean(), np.cos(thetas).mean()))
        centres = [tuple(self.run.pixmap.to_world(p.u, p.v)) for p in poses]
        pose = rigid_pose(centres, [self.placements[i].offset_m for i in ids], theta)
        return pose.x_m, pose.z_m, pose.angle_rad

    def _warn_markers(self, name: str, ids: list[int]) -> None:
        for i in ids:
            if self.lost.get(i):
                self.run.warnings.append(f"marker {i} ({name}): lost (NCC < {LOST_SCORE}) in "
                                         f"frames {_ranges(self.lost[i])}")
            if self.disagree.get(i):
                self.run.warnings.append(
                    f"marker {i} ({name}): followed and ArUco-detected centres differ by more "
                    f"than {MARKER_CHECK_PX} px in frames {_ranges(self.disagree[i])}")

    def _warn_gaps(self, name: str, ks: list[int], frames: int) -> None:
        missing = sorted(set(range(frames)) - set(ks))
        if not missing:
            return
        inside = [k for k in missing if ks[0] < k < ks[-1]]
        outside = [k for k in missing if k < ks[0] or k > ks[-1]]
        note = ([f"frames {_ranges(inside)} interpolated"] if inside else []) + (
            [f"frames {_ranges(outside)} left out"] if outside else [])
        self.run.warnings.append(f"{name}: no marker followed in {len(missing)} frames "
                                 f"({'; '.join(note)})")


def _marker_name(marker_id: int) -> str:
    return f"marker {marker_id}"


def _front_row(layout: Layout) -> dict[str, tuple[float, float, float, float]]:
    """Name -> (x, z, length, height) in the sled frame of the bundles facing the camera (R1)."""
    return {b.name: (b.centre_m[0], b.centre_m[2], b.size_m[0], b.size_m[2])
            for b in layout.bundles if b.name.endswith("R1")}


def _size(width_px: float, height_px: float) -> tuple[int, int]:
    return max(int(round(width_px)), 8), max(int(round(height_px)), 8)


def _ranges(frames: list[int]) -> str:
    """[1, 2, 3, 7] -> "1-3, 7"."""
    out, start = [], 0
    for k in range(1, len(frames) + 1):
        if k == len(frames) or frames[k] != frames[k - 1] + 1:
            first, last = frames[start], frames[k - 1]
            out.append(f"{first}-{last}" if last > first else f"{first}")
            start = k
    return ", ".join(out)

"""The objects of a wrapped unit, followed through the ArUco markers printed on the web.

The web hides the bundles, so ArUco names the objects carrying markers and the patch tracker
follows a box round each marker (marker, quiet zone and a little web): an 18 px marker's ArUco
corners give a noisy pose and are missed in some frames, the patch fitted to the first frame's
is sub-pixel. The object's centre is the marker's minus its placement offset turned by the
tracked rotation. ArUco runs again only every `MARKER_CHECK_EVERY` frames and where a marker
was lost or is not followed yet: to cross-check the patch tracker, re-acquire lost markers and
start late ones (a marker first seen late, or where its box does not fit in the frame).
"""

from __future__ import annotations

import math

import numpy as np

from calibration.camera_setup import MarkerPlacement
from calibration.trajectories import ObjectPath
from calibration.vision.checks import frame_ranges, gap_warnings
from calibration.vision.markers import (
    MarkerDetector,
    angle_rad,
    centre_px,
    rigid_pose,
    side_px,
)
from calibration.vision.objects import box_size
from calibration.vision.roi import PixelMap
from calibration.vision.tracking import LOST_SCORE, Frame, MultiTracker, PatchTracker, Pose

#: Side of a marker's tracked box in marker sides: the printed square, its white border (at
#: least one of a 4x4 code's six modules) and a little web.
MARKER_BOX_SIDES = 1.6
#: ArUco cross-checks the marker trackers every this many frames.
MARKER_CHECK_EVERY = 10
#: Tracked and detected marker centres further apart than this (px) are reported.
MARKER_CHECK_PX = 1.5

Results = dict[str, tuple[Pose, float]]


def marker_name(marker_id: int) -> str:
    """The name a marker's tracker goes by among the objects' trackers."""
    return f"marker {marker_id}"


class MarkerTracks:
    """Each carried marker followed by a patch tracker on its box from the frame ArUco first
    sees it in (see the module docstring); warnings go to `warnings`. `side_px`: the markers'
    side in the image, None when setup.toml does not give their size: then each box is sized
    from the marker's corners where ArUco first finds it."""

    def __init__(self, placements: list[MarkerPlacement], side_px: float | None,
                 detector: MarkerDetector, multi: MultiTracker, pixmap: PixelMap,
                 warnings: list[str]) -> None:
        self.placements = {p.id: p for p in placements}
        self.side_px, self.detector, self.multi = side_px, detector, multi
        self.pixmap, self.warnings = pixmap, warnings
        #: the object's rotation in the frame its marker was first seen (0 at rest, frame 0)
        self.theta0: dict[int, float] = {}
        self.poses: dict[int, dict[int, Pose]] = {}
        self.lost: dict[int, list[int]] = {}
        self.disagree: dict[int, list[int]] = {}
        #: frames a marker was detected in where its box leaves the frame, before it is followed
        self.cut: dict[int, list[int]] = {}

    def start(self, frame: Frame, found: dict[int, np.ndarray], sled_u: float,
              index: int = 0) -> None:
        """Trackers for the carried markers in `found` that have none yet."""
        for i, corners in found.items():
            placement = self.placements.get(i)
            if placement is None or i in self.theta0:
                continue
            centre = centre_px(corners)
            side = MARKER_BOX_SIDES * (self.side_px or side_px(corners))
            try:
                tracker = PatchTracker(frame, (float(centre[0]), float(centre[1])),
                                       box_size(side, side))
            except ValueError:  # its box leaves the frame: looked for again in the next one
                self.cut.setdefault(i, []).append(index)
                continue
            self.theta0[i] = self._object_theta(placement.object, index, corners)
            pose = Pose(float(centre[0]), float(centre[1]))
            self.multi.add(marker_name(i), tracker, pose, sled_u)
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

    def step(self, index: int, frame: Frame, sled_u: float, results: Results) -> None:
        """Record this frame's marker poses; ArUco on check frames, and where a marker was
        lost or is not followed yet."""
        lost = {i for i in self.theta0 if results[marker_name(i)][1] < LOST_SCORE}
        unfollowed = set(self.placements) - set(self.theta0)
        if not (lost or unfollowed or index % MARKER_CHECK_EVERY == 0):
            self._record(index, set(self.theta0), results)
            return
        found = self.detector.detect(frame)
        for i in lost & set(found):
            u, v = centre_px(found[i])
            predicted = Pose(float(u), float(v), results[marker_name(i)][0].theta)
            results[marker_name(i)] = self.multi.retry(marker_name(i), frame, predicted)
        for i in set(self.theta0) & set(found):
            pose, score = results[marker_name(i)]
            if score >= LOST_SCORE and math.dist((pose.u, pose.v),
                                                 centre_px(found[i])) > MARKER_CHECK_PX:
                self.disagree[i].append(index)
        self._record(index, set(self.theta0), results)
        self.start(frame, {i: c for i, c in found.items() if i in unfollowed}, sled_u, index)

    def _record(self, index: int, ids: set[int], results: Results) -> None:
        for i in ids:
            pose, score = results[marker_name(i)]
            if score < LOST_SCORE:
                self.lost[i].append(index)
            else:
                self.poses[i][index] = pose

    def carriers(self) -> dict[str, list[int]]:
        """The carrying objects by name, each with its markers' ids."""
        return {name: sorted(i for i, p in self.placements.items() if p.object == name)
                for name in sorted({p.object for p in self.placements.values()})}

    def poses_px(self, index: int) -> dict[str, Pose]:
        """Each carrying object's pose (pixels) in frame `index`, for those with a marker
        followed there."""
        out = {}
        for name, ids in self.carriers().items():
            seen = [i for i in ids if index in self.poses.get(i, {})]
            if seen:
                x, z, theta = self._pose(index, seen)
                u, v = self.pixmap.to_px(x, z)
                out[name] = Pose(float(u), float(v), theta)
        return out

    def paths(self, frames: int, fps: float) -> dict[str, ObjectPath]:
        """Per carrying object, its pose in every frame one of its markers is followed in; gaps
        inside the run are interpolated, frames outside it left out, and both reported."""
        out = {}
        for name, ids in self.carriers().items():
            self._warn_markers(name, ids)
            ks, values = [], []
            for k in range(frames):
                seen = [i for i in ids if k in self.poses.get(i, {})]
                if seen:
                    ks.append(k)
                    values.append(self._pose(k, seen))
            if not ks:
                never = "followed" if any(i in self.cut for i in ids) else "detected"
                self.warnings.append(f"{name}: markers {ids} never {never}; not tracked")
                continue
            self.warnings.extend(gap_warnings(name, ks, frames))
            span = np.arange(ks[0], ks[-1] + 1)
            vals = np.array(values)
            x, z, a = (np.interp(span, ks, vals[:, j]) for j in range(3))
            out[name] = ObjectPath(span / fps, x, z, a)
        return out

    def _pose(self, k: int, ids: list[int]) -> tuple[float, float, float]:
        poses = [self.poses[i][k] for i in ids]
        thetas = np.array([p.theta + self.theta0[i] for p, i in zip(poses, ids, strict=True)])
        theta = float(np.arctan2(np.sin(thetas).mean(), np.cos(thetas).mean()))
        centres = [tuple(self.pixmap.to_world(p.u, p.v)) for p in poses]
        pose = rigid_pose(centres, [self.placements[i].offset_m for i in ids], theta)
        return pose.x_m, pose.z_m, pose.angle_rad

    def _warn_markers(self, name: str, ids: list[int]) -> None:
        for i in ids:
            if self.cut.get(i):
                self.warnings.append(f"marker {i} ({name}): detected where its box leaves the "
                                     f"frame in frames {frame_ranges(self.cut[i])}, not "
                                     "followed there")
            if self.lost.get(i):
                self.warnings.append(f"marker {i} ({name}): lost (NCC < {LOST_SCORE}) in "
                                     f"frames {frame_ranges(self.lost[i])}")
            if self.disagree.get(i):
                self.warnings.append(
                    f"marker {i} ({name}): followed and ArUco-detected centres differ by more "
                    f"than {MARKER_CHECK_PX} px in frames {frame_ranges(self.disagree[i])}")

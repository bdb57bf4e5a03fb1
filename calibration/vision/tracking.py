"""Multi-object tracking: every object followed against its own first-frame appearance.

Identities come from the first-frame detections and never change afterwards: each tracker
only searches a few pixels around its prediction (the sled's motion from the profile plus the
object's own recent motion relative to the sled: 8 px either side, walked on to at most 24 px
while the peak lies on the window's edge), far less than the distance to a neighbour, so a
tracker cannot jump to the bundle next to it. Measuring against the first frame rather
than the previous one keeps sub-pixel errors from accumulating into drift.

Trackers (the `kind` names `track()` and the benchmarks use):
- ``ncc+flow`` (default): NCC of the reference patch around the prediction (sub-pixel peak),
  then Farnebäck on the reference vs the frame warped back by that estimate for the residual
  translation and the rotation.
- ``ncc``: the NCC step alone (translation only).
- ``flow``: Farnebäck refinements alone, no NCC search (fails when the prediction is off by
  more than Farnebäck's window).
- ``chain``: the paper's order, frame-to-frame Farnebäck mean displacement summed (drifts).
- ``mil``: OpenCV's TrackerMIL; box centre only, integer pixels. (OpenCV's network trackers,
  DaSiamRPN, Nano and Vit, need ONNX models that opencv-python-headless does not ship.)

Every tracker's score is the NCC of the object's first-frame patch with the frame at the pose
it reports (for ``ncc`` and ``ncc+flow``, the search's peak), so a tracker that went astray
scores low and the object counts as lost (`LOST_SCORE`) instead of being reported where it is
not. A neighbour that looks alike (the bundles' labels) can still score high: jumps to one are
what `checks.swap_warnings` looks for.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Protocol

import cv2
import numpy as np

from calibration.vision.detection import ncc, subpixel_peak
from calibration.vision.flow import FARNEBACK_LARGE, RigidFlow, rotation_px, warp_to_reference
from calibration.vision.roi import Box

#: NCC score under which an object counts as lost in a frame.
LOST_SCORE = 0.5
#: ncc+flow skips the NCC search in a frame when the last frame's result was this close (px) to
#: its prediction: the motion is then smooth enough for Farnebäck's window alone.
SKIP_NCC_PX = 0.25
#: Search windows an NCC search may walk through while its peak lies on a window's edge (each
#: `PatchTracker.search_px` either side): a found object up to 3 x 8 px from its prediction.
MAX_SEARCHES = 3
OWN_TRACKERS = ("ncc+flow", "ncc", "flow", "chain")
OPENCV_TRACKERS = ("mil",)


@dataclass(frozen=True)
class Pose:
    """Where the object's reference centre is in a frame (px) and its rotation since the first
    frame (rad, world convention: counter-clockwise with z up)."""

    u: float
    v: float
    theta: float = 0.0


@dataclass(frozen=True)
class Frame:
    """A grayscale crop of a video frame and where its top-left pixel is in the full frame."""

    gray: np.ndarray
    x0: int = 0
    y0: int = 0

    def local(self, pose: Pose) -> tuple[float, float]:
        return pose.u - self.x0, pose.v - self.y0


class Tracker(Protocol):
    """One object's tracker: `update` returns the pose in this frame and a confidence in [0, 1]
    (below `LOST_SCORE`: not found; the pose is then the prediction)."""

    box_size: tuple[int, int]

    def update(self, frame: Frame, predicted: Pose) -> tuple[Pose, float]: ...


@dataclass(frozen=True)
class Reference:
    """An object's first-frame patch and its centre in the patch, to score a pose by."""

    patch: np.ndarray
    centre: tuple[float, float]

    @classmethod
    def around(cls, frame: Frame, centre: tuple[float, float], size: tuple[int, int]
               ) -> Reference:
        """The patch of `size` centred on `centre` (resampled: a centre between pixels)."""
        ref_centre = _patch_centre(size)
        return cls(warp_to_reference(frame.gray, frame.local(Pose(*centre)), 0.0, ref_centre,
                                     size), ref_centre)

    def score(self, frame: Frame, pose: Pose) -> float:
        """NCC of the patch with `frame` warped back at `pose`: near 1 where the object is as it
        first looked, low where it is not."""
        height, width = self.patch.shape
        crop = warp_to_reference(frame.gray, frame.local(pose), pose.theta, self.centre,
                                 (width, height))
        return float(ncc(crop, self.patch)[0, 0])


class PatchTracker:
    """An object followed by matching its first-frame patch (see the module docstring)."""

    def __init__(self, frame: Frame, centre: tuple[float, float], size: tuple[int, int],
                 kind: str = "ncc+flow", search_px: int = 8, pad_px: int = 6) -> None:
        if kind not in ("ncc+flow", "ncc", "flow"):
            raise ValueError(f"unknown patch tracker {kind!r}")
        box = Box.around(centre[0] - frame.x0, centre[1] - frame.y0, *size)
        padded = box.grow(pad_px)
        h, w = frame.gray.shape
        if padded.x0 < 0 or padded.y0 < 0 or padded.x1 > w or padded.y1 > h:
            raise ValueError("object box leaves the frame")
        self.reference = np.ascontiguousarray(frame.gray[box.y0:box.y1, box.x0:box.x1])
        self.ref_centre = (centre[0] - frame.x0 - box.x0, centre[1] - frame.y0 - box.y0)
        self.box_size = (box.width, box.height)
        self.kind, self.search_px, self.pad_px = kind, search_px, pad_px
        self.first = Reference(self.reference, self.ref_centre)
        self.predicted_well = False
        # Farnebäck runs on the box plus a pad, so its window has real pixels at the box's edge
        self.flow = None if kind == "ncc" else RigidFlow(
            np.ascontiguousarray(frame.gray[padded.y0:padded.y1, padded.x0:padded.x1]),
            (self.ref_centre[0] + pad_px, self.ref_centre[1] + pad_px), border=pad_px + 2)

    def update(self, frame: Frame, predicted: Pose) -> tuple[Pose, float]:
        """NCC then Farnebäck; NCC is skipped while the prediction keeps landing within
        `SKIP_NCC_PX` of the result (Farnebäck alone captures that; the score is then the
        reference's at the result). A skipped frame whose result lands farther (a slide
        starting or stopping) is matched again from that result: one Farnebäck step from a
        missed prediction leaves up to a pixel. One whose result scores low (the object
        covered: over a plain cover Farnebäck finds no motion and lands on the prediction) is
        matched again from the prediction, and is lost if the search finds it nowhere."""
        skipped = self.kind == "ncc+flow" and self.predicted_well
        pose, score = self._match(frame, predicted, search=not skipped)
        if skipped and score < LOST_SCORE:
            pose, score = self._match(frame, predicted, search=True)
        elif skipped and not self._near(pose, predicted):
            pose, score = self._match(frame, pose, search=True)
        if score < LOST_SCORE:
            self.predicted_well = False
            return predicted, score
        self.predicted_well = self._near(pose, predicted)
        return pose, score

    def _match(self, frame: Frame, start: Pose, search: bool) -> tuple[Pose, float]:
        """The pose from `start` and its score: the NCC search's peak where it searched (always
        for ``ncc``, when `search` for ``ncc+flow``, never for ``flow``), else the
        reference's at the result."""
        searched = self.kind == "ncc" or (self.kind == "ncc+flow" and search)
        pose, score = start, 0.0
        if searched:
            pose, score = self._ncc(frame, pose)
            if score < LOST_SCORE:
                return pose, score
        if self.flow is not None:
            for _ in range(2 if self.kind == "flow" else 1):
                pose = self._refine(frame, pose)
        if not searched:
            score = self.first.score(frame, pose)
        return pose, score

    @staticmethod
    def _near(pose: Pose, predicted: Pose) -> bool:
        return math.hypot(pose.u - predicted.u, pose.v - predicted.v) < SKIP_NCC_PX

    def _ncc(self, frame: Frame, pose: Pose) -> tuple[Pose, float]:
        """The NCC search's peak around `pose`. A peak on the search window's edge that scores
        as found is not bracketed (the object may lie beyond, as one that stopped while hidden
        does from its prediction): the search goes on from it, up to `MAX_SEARCHES` windows;
        one still on an edge then counts as not found (score 0), not as where the object is."""
        for _ in range(MAX_SEARCHES):
            pose, score, on_edge = self._search(frame, pose)
            if not (on_edge and score >= LOST_SCORE):
                return pose, score
        return pose, 0.0

    def _search(self, frame: Frame, pose: Pose) -> tuple[Pose, float, bool]:
        """One search window's peak, its score, and whether it lies on the window's edge."""
        m = self.search_px
        crop = warp_to_reference(frame.gray, frame.local(pose), pose.theta, self.ref_centre,
                                 self.box_size, m)
        scores = ncc(crop, self.reference)
        row, col = (int(k) for k in np.unravel_index(int(np.argmax(scores)), scores.shape))
        dc, dr = subpixel_peak(scores, row, col)
        t = rotation_px(pose.theta) @ np.array([col + dc - m, row + dr - m])
        on_edge = row in (0, scores.shape[0] - 1) or col in (0, scores.shape[1] - 1)
        return (replace(pose, u=pose.u + t[0], v=pose.v + t[1]), float(scores[row, col]),
                on_edge)

    def _refine(self, frame: Frame, pose: Pose) -> Pose:
        assert self.flow is not None
        warped = warp_to_reference(frame.gray, frame.local(pose), pose.theta, self.ref_centre,
                                   self.box_size, self.pad_px)
        motion = self.flow.measure(warped)
        t = rotation_px(pose.theta) @ np.array([motion.du, motion.dv])
        return Pose(pose.u + t[0], pose.v + t[1], pose.theta + motion.dtheta)


class ChainFlowTracker:
    """The paper's order: Farnebäck between consecutive frames inside the box, the weighted mean
    displacement added up. Kept for the comparison: its errors accumulate."""

    def __init__(self, frame: Frame, centre: tuple[float, float], size: tuple[int, int]) -> None:
        self.box_size = size
        self.previous, self.pose = frame, Pose(*centre)
        self.first = Reference.around(frame, centre, size)

    def update(self, frame: Frame, predicted: Pose) -> tuple[Pose, float]:
        centre = _patch_centre(self.box_size)
        ref = warp_to_reference(self.previous.gray, self.previous.local(self.pose), 0.0, centre,
                                self.box_size)
        cur = warp_to_reference(frame.gray, frame.local(predicted), 0.0, centre, self.box_size)
        motion = RigidFlow(ref, centre, border=2, farneback=FARNEBACK_LARGE).measure(cur)
        self.pose = Pose(predicted.u + motion.du, predicted.v + motion.dv,
                         self.pose.theta + motion.dtheta)
        self.previous = frame
        score = self.first.score(frame, self.pose)
        return (self.pose if score >= LOST_SCORE else predicted), score


def _patch_centre(size: tuple[int, int]) -> tuple[float, float]:
    return (size[0] - 1) / 2, (size[1] - 1) / 2


class OpenCVTracker:
    """cv2's TrackerMIL (box centre only). It keeps its own state in full-frame coordinates, so
    it must be given whole frames (offset 0)."""

    def __init__(self, frame: Frame, centre: tuple[float, float], size: tuple[int, int]) -> None:
        self.box_size = size
        self.tracker = cv2.TrackerMIL.create()
        box = Box.around(centre[0], centre[1], *size)
        self.offset = (centre[0] - (box.x0 + (box.width - 1) / 2),
                       centre[1] - (box.y0 + (box.height - 1) / 2))
        self.tracker.init(_bgr(frame.gray), (box.x0, box.y0, box.width, box.height))
        self.first = Reference.around(frame, centre, size)

    def update(self, frame: Frame, predicted: Pose) -> tuple[Pose, float]:
        """The box OpenCV's tracker reports, scored by the reference there (its own "ok" says
        only that it placed a box)."""
        ok, (x, y, w, h) = self.tracker.update(_bgr(frame.gray))
        if not ok:
            return predicted, 0.0
        pose = Pose(x + (w - 1) / 2 + self.offset[0], y + (h - 1) / 2 + self.offset[1])
        score = self.first.score(frame, pose)
        return (pose if score >= LOST_SCORE else predicted), score


def _bgr(gray: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)


def check_tracker(kind: str) -> None:
    """`ValueError` unless `kind` names a tracker (see the module docstring): an unknown one
    would only fail object by object."""
    if kind not in OWN_TRACKERS + OPENCV_TRACKERS:
        raise ValueError(f"unknown tracker {kind!r}; known: "
                         f"{', '.join(OWN_TRACKERS + OPENCV_TRACKERS)}")


def make_tracker(kind: str, frame: Frame, centre: tuple[float, float],
                 size: tuple[int, int]) -> Tracker:
    """A tracker of `kind` (see the module docstring) started on an object in `frame`."""
    if kind == "chain":
        return ChainFlowTracker(frame, centre, size)
    if kind in OPENCV_TRACKERS:
        return OpenCVTracker(frame, centre, size)
    return PatchTracker(frame, centre, size, kind)


@dataclass
class _History:
    """The last two poses relative to the sled (u) for a constant-velocity prediction."""

    poses: list[Pose]
    sled_u: list[float]

    def predict(self, sled_u: float) -> Pose:
        last, ref = self.poses[-1], self.sled_u[-1]
        if len(self.poses) < 2:
            return Pose(last.u + sled_u - ref, last.v, last.theta)
        prev, prev_ref = self.poses[-2], self.sled_u[-2]
        rel_vu = (last.u - ref) - (prev.u - prev_ref)
        return Pose(last.u - ref + sled_u + rel_vu, 2 * last.v - prev.v,
                    2 * last.theta - prev.theta)

    def push(self, pose: Pose, sled_u: float) -> None:
        self.poses = [*self.poses[-1:], pose]
        self.sled_u = [*self.sled_u[-1:], sled_u]


class MultiTracker:
    """Named trackers stepped together, each predicted from the sled shift and its own motion;
    the objects are independent, so they are updated on a small thread pool (OpenCV releases
    the GIL)."""

    def __init__(self, trackers: dict[str, Tracker], start: dict[str, Pose], threads: int = 2):
        self.trackers = trackers
        self.history = {name: _History([start[name]], [0.0]) for name in trackers}
        self.pool = ThreadPoolExecutor(threads) if threads > 1 else None

    def step(self, frame: Frame, sled_u: float) -> dict[str, tuple[Pose, float]]:
        """Poses and scores of every object in `frame`; `sled_u` is the sled's predicted u shift
        since the first frame. A lost object's history keeps its prediction."""
        def one(name: str) -> tuple[Pose, float]:
            return self.trackers[name].update(frame, self.history[name].predict(sled_u))

        run: Callable = self.pool.map if self.pool else map
        results = dict(zip(self.trackers, run(one, self.trackers), strict=True))
        for name, (pose, _) in results.items():
            self.history[name].push(pose, sled_u)
        return results

    def add(self, name: str, tracker: Tracker, pose: Pose, sled_u: float) -> None:
        """Follow one more object from this frame on (one first seen late)."""
        self.trackers[name] = tracker
        self.history[name] = _History([pose], [sled_u])

    def retry(self, name: str, frame: Frame, predicted: Pose) -> tuple[Pose, float]:
        """Update `name` again in the frame just stepped from a better prediction (an object
        its tracker lost, found by other means); the result replaces the step's."""
        pose, score = self.trackers[name].update(frame, predicted)
        history = self.history[name]
        history.poses[-1] = pose
        return pose, score

    def close(self) -> None:
        if self.pool:
            self.pool.shutdown()

"""`track --debug-video`: the recording with every followed object's box, centre and name drawn,
so a person can see at a glance where a tracker went wrong."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from calibration.vision.objects import TrackedObject
from calibration.vision.tracking import Pose
from wrapenv.config import InputError, make_ordinary

YELLOW, RED, WHITE = (0, 255, 255), (0, 0, 255), (255, 255, 255)


class DebugVideo:
    """An mp4v file the annotated frames are written to, in order; it appears at `path` when
    the `with` block ends normally, and not at all when it raises (an interrupted run)."""

    def __init__(self, path: Path, fps: float, size: tuple[int, int]) -> None:
        self.path = path
        fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
        os.close(fd)
        make_ordinary(name)
        self.partial = Path(name)
        self.writer = cv2.VideoWriter(name, cv2.VideoWriter.fourcc(*"mp4v"), fps, size)
        if not self.writer.isOpened():
            self.partial.unlink()
            raise InputError(str(path), "", "OpenCV cannot write a video there (it needs a "
                             "video suffix such as .mp4)")

    def __enter__(self) -> DebugVideo:
        return self

    def __exit__(self, kind: type[BaseException] | None, *exc: object) -> None:
        self.writer.release()
        if kind is None:
            os.replace(self.partial, self.path)
        else:
            self.partial.unlink(missing_ok=True)

    def draw(self, bgr: np.ndarray, index: int, objects: list[TrackedObject],
             poses: dict[str, Pose]) -> None:
        """Rotated box, centre dot and name of every object found in this frame."""
        image = bgr.copy()
        for obj in objects:
            pose = poses.get(obj.name)
            if pose is None:
                continue
            rect = ((pose.u, pose.v), obj.size_px, -math.degrees(pose.theta))
            corners = np.round(cv2.boxPoints(rect)).astype(np.int32)
            cv2.polylines(image, [corners], True, YELLOW, 1, cv2.LINE_AA)
            centre = (int(round(pose.u)), int(round(pose.v)))
            cv2.circle(image, centre, 3, RED, -1, cv2.LINE_AA)
            cv2.putText(image, obj.name, (centre[0] + 5, centre[1] - 5),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.4, YELLOW, 1, cv2.LINE_AA)
        cv2.putText(image, f"frame {index}", (10, 25), cv2.FONT_HERSHEY_SIMPLEX, 0.7, WHITE, 2,
                    cv2.LINE_AA)
        self.writer.write(image)

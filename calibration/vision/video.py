"""Reading a recording's video: its stated frame count, rate and size, and its frames decoded
ahead on a second thread; a cut-off end told apart from a whole one.

A file cut short (a copy interrupted, a camera that lost power) still opens: the container's
header states every frame, FFmpeg decodes those whose data is there and then the one the file
was cut inside, with its missing rows grey. To the tracker that frame looks like any other and
the objects crossing the cut come out tens of millimetres off. So when fewer frames decode than
the container states, the last one is not trusted: it is dropped and `truncated` says so (a file
cut exactly between two frames loses one good frame to this).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor, wait
from pathlib import Path

import cv2
import numpy as np

from wrapenv.config import InputError

# FFmpeg's own log (read when OpenCV first opens a video) would print lines such as "[mjpeg @
# 0x...] overread 8" on a damaged file; what matters is said once, as an error or a warning.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET


def open_video(path: Path) -> cv2.VideoCapture:
    """An opened capture of the video at `path`; `InputError` when it cannot be opened."""
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise InputError(str(path), "", "cannot open the video (unknown or damaged container)")
    return cap


class VideoReader:
    """A video's frames in order (BGR); `stated` frames per the container, `decoded` so far."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.cap = open_video(path)
        self.stated = int(self.cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.fps = float(self.cap.get(cv2.CAP_PROP_FPS))
        self.size = (int(self.cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
                     int(self.cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        self.decoded = 0
        self.truncated = False
        #: The frame being decoded on the reader thread while the caller works (None: none).
        self._pending: Future[np.ndarray | None] | None = None

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        # A caller that stops early (an error in its loop) leaves `frames` suspended with a
        # read in flight: releasing the capture under it deadlocks FFmpeg's scaler threads.
        if self._pending is not None:
            wait([self._pending])
        self.cap.release()

    def frames(self) -> Iterator[np.ndarray]:
        """Every trusted frame. A frame is handed out once the one after it has decoded (or
        failed to: the file ends there), and the one after that decodes on another thread
        while the caller works (OpenCV releases the GIL: decoding is a fifth of the time per
        frame)."""
        with ThreadPoolExecutor(1) as reader:
            current, following = self._read(), self._read()
            while current is not None:
                if following is None and self.decoded < self.stated:
                    self.truncated = True  # `current` may be the frame the file was cut inside
                    return
                pending = reader.submit(self._read) if following is not None else None
                self._pending = pending
                yield current
                current, following = following, pending.result() if pending else None
                self._pending = None

    def _read(self) -> np.ndarray | None:
        ok, bgr = self.cap.read()
        if not ok:
            return None
        self.decoded += 1
        return bgr

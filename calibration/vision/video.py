"""Reading a recording's video: its stated frame count, rate and size, and its frames decoded
ahead on a second thread."""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from wrapenv.config import InputError


class VideoReader:
    """A video's frames in order (BGR); `stated` frames per the container, `decoded` so far."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.cap = cv2.VideoCapture(str(path))
        if not self.cap.isOpened():
            self.cap.release()
            raise InputError(str(path), "", "cannot open the video")
        self.stated = int(self.cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.fps = float(self.cap.get(cv2.CAP_PROP_FPS))
        self.size = (int(self.cap.get(cv2.CAP_PROP_FRAME_WIDTH)),
                     int(self.cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        self.decoded = 0

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cap.release()

    def frames(self) -> Iterator[np.ndarray]:
        """Every frame that decodes; the next one decodes on another thread while the caller
        works on this one (OpenCV releases the GIL: decoding is a fifth of the time per
        frame)."""
        with ThreadPoolExecutor(1) as reader:
            current = self._read()
            while current is not None:
                pending = reader.submit(self._read)
                yield current
                current = pending.result()

    def _read(self) -> np.ndarray | None:
        ok, bgr = self.cap.read()
        if not ok:
            return None
        self.decoded += 1
        return bgr

"""Recordings, vision and the inverse problems that fit the bench to them (issues 5 and 6).

OpenCV runs code chosen for the processor at hand (SSE4, AVX2, AVX-512, Intel's IPP), and those
paths round differently: the 2-layer example's 0.45 g take, synthesised and tracked with AVX2
and without, differed in its video's bytes and in its tracked paths by up to 14 µm, and one
falling bundle's by 81 mm; the same calibration then fitted other coefficients on another
machine. OpenCV's baseline code (SSE2/SSE3, which every x86-64 has) gives the same frames and
paths everywhere (tests/calibration/test_determinism.py); synthesis takes about a fifth
longer, tracking about 4 % (docs/calibration.md, "The same takes on every processor").
"""

from collections.abc import Iterator
from contextlib import contextmanager

import cv2

cv2.setUseOptimized(False)


@contextmanager
def opencv_threads(count: int) -> Iterator[None]:
    """OpenCV's own thread count for a block (0: none), restored after it."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(count)
    try:
        yield
    finally:
        cv2.setNumThreads(before)

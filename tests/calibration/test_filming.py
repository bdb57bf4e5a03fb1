"""The video writer of synthetic recordings (calibration/filming.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calibration import filming


class _WriterWithoutQuality:
    """A cv2.VideoWriter that opens but refuses the quality setting; it records its release."""

    released: list[bool] = []

    def __init__(self, *args: object) -> None:
        pass

    @staticmethod
    def fourcc(*code: str) -> int:
        return 0

    def isOpened(self) -> bool:  # noqa: N802 (cv2's name)
        return True

    def set(self, prop: int, value: float) -> bool:
        return False

    def release(self) -> None:
        self.released.append(True)


def test_a_writer_refusing_the_quality_is_released(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """The writer is let go before the error: it used to keep the file and its encoder."""
    monkeypatch.setattr(filming.cv2, "VideoWriter", _WriterWithoutQuality)
    monkeypatch.setattr(_WriterWithoutQuality, "released", [])  # this run's releases only
    with pytest.raises(RuntimeError, match="quality"):
        filming.write_video(tmp_path / "video.avi", [np.zeros((8, 8, 3), np.uint8)], 10.0,
                            (8, 8))
    assert _WriterWithoutQuality.released == [True]

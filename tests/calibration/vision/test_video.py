"""Reading a recording's video: every frame of a whole file, and a file cut short losing the
frame it was cut inside (FFmpeg decodes that one with its missing rows grey)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from calibration.filming import write_video
from calibration.vision.video import VideoReader
from tests.calibration.vision.vision_frames import texture

FRAMES = 12


@pytest.fixture
def video(tmp_path: Path) -> Path:
    path = tmp_path / "video.avi"
    image = np.dstack([texture(96, 128, seed=0)] * 3)
    write_video(path, (np.roll(image, 3 * k, axis=1) for k in range(FRAMES)), 10.0, (128, 96))
    return path


def _all(path: Path) -> tuple[list[np.ndarray], VideoReader]:
    with VideoReader(path) as reader:
        return list(reader.frames()), reader


def test_a_whole_video_gives_every_frame(video: Path) -> None:
    frames, reader = _all(video)
    assert len(frames) == reader.stated == reader.decoded == FRAMES
    assert not reader.truncated


def test_a_cut_video_drops_the_frame_it_was_cut_inside(video: Path, tmp_path: Path,
                                                       capfd: pytest.CaptureFixture) -> None:
    """...silently: the warning is track's one line, not FFmpeg's "[mjpeg @ 0x...] overread"."""
    whole, _ = _all(video)
    cut = tmp_path / "cut.avi"
    data = video.read_bytes()
    cut.write_bytes(data[:len(data) * 2 // 3])  # inside frame 8 of 12
    frames, reader = _all(cut)
    assert reader.truncated and reader.stated == FRAMES
    assert len(frames) == reader.decoded - 1 > 0
    for kept, original in zip(frames, whole, strict=False):
        np.testing.assert_array_equal(kept, original)
    assert capfd.readouterr().err == ""

"""How small may synth's ArUco markers be for `track` to find them? (`synth.MIN_MARKER_PX`)

Synthesizes the 2-layer example wrapped in Kraft at 0.5 g (the sled's two markers and the web's
six) at several image sizes and marker sides, runs `track`'s detector on every frame, and
prints the markers' side in px and the share of markers found per frame (mean and least).

    python -m benchmarks.marker_size
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np

from calibration.recording import Recording
from calibration.synth import synthesize
from calibration.vision.markers import MarkerDetector
from calibration.vision.tracking import Frame
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

LOAD = "examples/pet_2layer_columnar.toml"
WRAP = "examples/wrap_kraft_2layer.toml"
#: (image size, marker side in m): the smallest image synth makes well, then larger ones
CASES = (((960, 600), 0.05), ((960, 600), 0.06), ((960, 600), 0.075), ((1280, 800), 0.06),
         ((1280, 800), 0.075), ((1600, 1000), 0.06), ((1920, 1200), 0.06))


def found_per_frame(rec: Recording) -> list[int]:
    """How many of the recording's markers the detector finds in each frame."""
    assert rec.markers is not None
    detector = MarkerDetector(rec.markers.dictionary)
    placed = {p.id for p in rec.markers.placements}
    video, counts = cv2.VideoCapture(str(rec.video)), list[int]()
    try:
        while True:
            ok, frame = video.read()
            if not ok:
                return counts
            found = detector.detect(Frame(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)))
            counts.append(len(placed & set(found)))
    finally:
        video.release()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--level", type=float, default=0.5)
    args = parser.parse_args(argv)
    load = LoadUnit.from_toml(LOAD)
    wrap = WrapFormat.from_toml(WRAP, load.load_height_m)
    print(f"{'image':>9}  {'marker m':>8}  {'side px':>7}  {'found, mean':>11}  {'least':>5}")
    for size, side_m in CASES:
        with tempfile.TemporaryDirectory() as folder:
            rec = synthesize(load, Path(folder) / "rec", wrap=wrap, level_g=args.level,
                             size=size, marker_size_m=side_m)
            counts = found_per_frame(rec)
        assert rec.markers is not None
        n = len(rec.markers.placements)
        print(f"{size[0]:>4}x{size[1]:<4}  {side_m:8.3f}  {side_m * rec.px_per_m:7.1f}  "
              f"{np.mean(counts) / n:11.0%}  {min(counts):>2} of {n}", flush=True)


if __name__ == "__main__":
    main()

"""Tracker comparison on synthetic recordings: accuracy against truth.json and speed.

Rows: this project's trackers (`calibration.vision.tracking`: ncc+flow, ncc, flow, chain) and
OpenCV 5's TrackerMIL (DaSiamRPN, Nano and Vit need ONNX model files that opencv-python-headless
does not ship and that cannot be fetched offline, so they are not offered). Columns:
mean and worst per-object RMS and max displacement error (mm) over the frames each object is
reported in, objects whose error ever exceeds half a bundle's width (a swap or a loss), the
share of object-frames reported (the rest were scored lost and said so), and fps of the whole
`track` run.

    python -m benchmarks.trackers [--size 960 600]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_track import CACHE, cached_recording
from calibration.recording import Recording, Truth
from calibration.track import track
from calibration.trajectories import error_vs_truth
from calibration.vision.tracking import OPENCV_TRACKERS, OWN_TRACKERS
from wrapenv.config import InputError

RECORDINGS = (("examples/pet_2layer_columnar.toml", 0.4, None),
              ("examples/pet_3layer_columnar.toml", 0.3, None))
#: An object's error beyond this (m) means its tracker followed something else.
SWAP_M = 0.095


def row(rec: Recording, kind: str) -> str:
    start = time.perf_counter()
    try:
        result = track(rec, tracker=kind)
    except InputError as exc:
        # track's own checks refused what this tracker followed (e.g. a sled that departs
        # from the profile's path): that is the tracker's result here
        return f"| {kind:9} | refused by track: {exc.field}: {exc.message.split(':')[0]} |"
    seconds = time.perf_counter() - start
    lengths = [len(p.t_s) for p in result.trajectories.objects.values()]
    frames = max(lengths)
    # a frame whose pose scores too low is reported lost and left out of the errors
    tracked = 100 * sum(lengths) / (frames * len(lengths))
    errors = error_vs_truth(result.trajectories, Truth.read(rec.folder).objects).values()
    rms = np.array([e.rms_m for e in errors]) * 1e3
    worst = np.array([e.max_m for e in errors]) * 1e3
    swaps = int(np.sum(worst > SWAP_M * 1e3))
    return (f"| {kind:9} | {rms.mean():7.2f} | {rms.max():7.2f} | {worst.max():8.2f} "
            f"| {swaps:5d} | {tracked:7.1f} | {frames / seconds:6.1f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(960, 600))
    parser.add_argument("--cache", type=Path, default=CACHE)
    args = parser.parse_args()
    for load, level, wrap in RECORDINGS:
        rec = cached_recording(load, level, tuple(args.size), wrap=wrap, cache=args.cache)
        print(f"\n{load} at {level} g, {args.size[0]}x{args.size[1]}, {rec.px_per_m:.0f} px/m")
        print("| tracker   | RMS avg | RMS max | max (mm) | swaps | tracked |    fps |")
        print("|-----------|---------|---------|----------|-------|---------|--------|")
        for kind in OWN_TRACKERS + OPENCV_TRACKERS:
            print(row(rec, kind), flush=True)


if __name__ == "__main__":
    main()

"""Accuracy of `wrapbench track` against truth.json on the issue's three synthetic recordings at
full size (1920x1200, 20 fps): the 2-layer example at 0.4 g (second layer slides), the 3-layer
example at 0.3 g (columns tip) and the 2-layer example Kraft-wrapped at 0.5 g (markers on the
web). Per recording: worst per-object RMS and max displacement error, identity swaps (an object
whose error ever exceeds half a bundle's width) and warnings; then every object's figures.

    python -m benchmarks.track_accuracy [--size 1920 1200]
"""

from __future__ import annotations

import argparse

from benchmarks.bench_track import CACHE, cached_recording
from benchmarks.trackers import SWAP_M
from calibration.recording import Truth
from calibration.track import track
from calibration.trajectories import error_vs_truth

RECORDINGS = (("examples/pet_2layer_columnar.toml", 0.4, None),
              ("examples/pet_3layer_columnar.toml", 0.3, None),
              ("examples/pet_2layer_columnar.toml", 0.5, "examples/wrap_kraft_2layer.toml"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(1920, 1200))
    args = parser.parse_args()
    for load, level, wrap in RECORDINGS:
        rec = cached_recording(load, level, tuple(args.size), wrap=wrap, cache=CACHE)
        result = track(rec)
        errors = error_vs_truth(result.trajectories, Truth.read(rec.folder).objects)
        worst_rms = max(errors.items(), key=lambda kv: kv[1].rms_m)
        worst_max = max(errors.items(), key=lambda kv: kv[1].max_m)
        swaps = sum(e.max_m > SWAP_M for e in errors.values())
        print(f"\n{load} at {level} g{' wrapped ' + wrap if wrap else ''}: "
              f"{args.size[0]}x{args.size[1]}, {rec.px_per_m:.0f} px/m, {len(errors)} objects; "
              f"worst RMS {1e3 * worst_rms[1].rms_m:.2f} mm ({worst_rms[0]}), worst max "
              f"{1e3 * worst_max[1].max_m:.2f} mm ({worst_max[0]}), swaps {swaps}")
        for w in result.warnings:
            print("  warning:", w)
        for name, e in sorted(errors.items()):
            print(f"  {name:8} RMS {1e3 * e.rms_m:5.2f} mm  max {1e3 * e.max_m:5.2f} mm  "
                  f"start offset {1e3 * e.offset_m:5.2f} mm  {e.frames} frames")


if __name__ == "__main__":
    main()

"""What the best calibration could predict of a held-out take: replays with the very values the
recording was made with, each after a different settling time, against the recording.

Issue 13 asks a third level, not fitted, to be predicted within 15 % of its recorded slide. A
replay differs from another only in the state its unit starts the pulse from (a unit settled
longer starts from slightly different contacts), as repeated bench tests do; near a pair's
threshold those runs fall into distinct outcomes (a bundle slides or holds), and the recording
is one of them. Printed per held-out take of `benchmarks.bench_calibrate`'s cases: the layer
that slid most in the recording, its recorded slide, and the slide of each replay (the layer's
mean slip at the end of its windows, clipped at the support's edge, as `wrapbench calibrate
--validate` compares them), with the replays' mean and spread.

    python -m benchmarks.held_out_modes [--case columnar2] [--workers 2]
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import numpy as np

from benchmarks.bench_calibrate import CASES, observation, true_calibration
from calibration.validate import validate
from wrapenv.bench import SimSettings

#: Settling times of the replays: the bench's 0.3 s, then every 0.05 s to 1.2 s.
SETTLE_S = tuple(round(0.3 + 0.05 * k, 2) for k in range(19))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", nargs="+", choices=list(CASES), default=["columnar2"])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    with ProcessPoolExecutor(args.workers) as pool:
        for case in args.case:
            for take in CASES[case][1]:
                obs, truth = observation(take)
                calibration = true_calibration(truth)
                slides = []
                for settle in SETTLE_S:
                    (check,) = validate([obs], calibration, pool,
                                        replace(SimSettings(), settle_s=settle), repeats=1)
                    layer, slide = check.largest
                    slides.append(slide.predicted_m)
                recorded = slide.recorded_m
                mm = np.array(slides) * 1e3
                print(f"{case}, held out at {take.level_g} g, layer {layer}: recorded "
                      f"{recorded * 1e3:.1f} mm; {len(mm)} replays with the true values "
                      f"(settled {SETTLE_S[0]}-{SETTLE_S[-1]} s): mean {mm.mean():.1f} mm, "
                      f"spread {mm.std(ddof=1):.1f} mm, range {mm.min():.1f} to {mm.max():.1f}; "
                      f"within 15 % of the recording: "
                      f"{np.sum(np.abs(mm - recorded * 1e3) <= 0.15 * abs(recorded * 1e3))}")
                print("  replays, mm: " + " ".join(f"{v:.0f}" for v in mm), flush=True)


if __name__ == "__main__":
    main()

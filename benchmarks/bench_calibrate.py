"""Calibration end to end (synth -> track -> calibrate) on recordings whose true parameters the
fit is not told.

1. Friction: two recordings of `examples/calibration_slide.toml` (two bundles sliding apart on
   a stopped pallet) at 0.45 g and 0.55 g; the seed draws the true friction within ±10 % of the
   file's values, so the fit starts from wrong values. Both are tracked by `track` and fitted
   jointly by CMA-ES and by the source paper's gradient descent with momentum, with the same
   budget. Printed per method: simulations, wall time, residual RMS, the fitted pallet-bundle
   pair with its standard deviations and its error against the truth.
2. Wrap: the same unit in one layer of LLDPE (`examples/wrap_lldpe_1layer_light.toml`) whose
   true stiffness is 1.3 times the material card's, recorded at 1920x1200 (the web's markers
   need the pixels), fitted with `--params all` (friction on the bare recordings, then the
   wrap's scales on the wrapped one) by CMA-ES.

    python -m benchmarks.bench_calibrate [--budget 240] [--size 960 600] [--workers 2]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from benchmarks.bench_track import CACHE
from calibration.fit import METHODS, FitSettings, fit
from calibration.recording import Recording, Truth
from calibration.replay import observe
from calibration.synth import synthesize
from calibration.track import track
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

LOAD = "examples/calibration_slide.toml"
LEVELS = (0.45, 0.55)
SEED, JITTER = 7, 0.1
WRAP, WRAP_LEVEL, WRAP_SIZE, TRUE_STIFFNESS = ("examples/wrap_lldpe_1layer_light.toml", 0.55,
                                               (1920, 1200), 1.3)


def recording(level_g: float, size: tuple[int, int], wrap: str | None = None) -> Recording:
    tag = f"-{Path(wrap).stem}-x{TRUE_STIFFNESS}" if wrap else ""
    folder = CACHE / f"calibration-{level_g}g-{size[0]}x{size[1]}-seed{SEED}{tag}"
    if not (folder / "truth.json").exists():
        folder.parent.mkdir(parents=True, exist_ok=True)
        extra = ({"wrap": WrapFormat.from_toml(wrap), "stiffness_scale": TRUE_STIFFNESS,
                  "marker_size_m": 0.075} if wrap else {})
        synthesize(LoadUnit.from_toml(LOAD), folder, level_g=level_g, seed=SEED, size=size,
                   friction_jitter=JITTER, **extra)
    return Recording.read(folder)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=int, default=240)
    parser.add_argument("--size", type=int, nargs=2, default=(960, 600))
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    observations, truth = [], None
    for level in LEVELS:
        rec = recording(level, tuple(args.size))
        truth = Truth.read(rec.folder).params["friction"]["pallet_bundle"]
        obs = observe(rec, track(rec).trajectories)
        print(f"{Path(rec.folder).name}: {rec.px_per_m:.0f} px/m, slipped {sorted(obs.slipped)}")
        observations.append(obs)
    print(f"truth pallet_bundle: static {truth['static']:.4f}, kinetic {truth['kinetic']:.4f} "
          f"(the load file says 0.35 / 0.28)")
    for method in METHODS:
        t0 = time.perf_counter()
        result = fit(observations, FitSettings(method=method, budget=args.budget,
                                               workers=args.workers))
        wall = time.perf_counter() - t0
        pair = result.calibration.friction["pallet_bundle"]
        print(f"{method:9s}: {result.simulations} simulations, {wall:.0f} s, residual RMS "
              f"{1e3 * result.residual_rms_m:.2f} mm; static {pair.static:.4f} ± "
              f"{pair.static_std:.4f} (error {pair.static - truth['static']:+.4f}), kinetic "
              f"{pair.kinetic:.4f} ± {pair.kinetic_std:.4f} "
              f"(error {pair.kinetic - truth['kinetic']:+.4f})", flush=True)
    wrapped = recording(WRAP_LEVEL, WRAP_SIZE, WRAP)
    tracked = track(wrapped)
    observations.append(observe(wrapped, tracked.trajectories))
    print(f"{Path(wrapped.folder).name}: {wrapped.px_per_m:.0f} px/m, tracked "
          f"{sorted(tracked.trajectories.objects)}")
    t0 = time.perf_counter()
    result = fit(observations, FitSettings(params="all", budget=args.budget,
                                           workers=args.workers))
    cal = result.calibration
    print(f"wrap (all): {result.simulations} simulations, {time.perf_counter() - t0:.0f} s, "
          f"residual RMS {1e3 * result.residual_rms_m:.2f} mm; stiffness scale "
          f"{cal.stiffness_scale:.3f} ± {cal.stiffness_scale_std:.3f} (true {TRUE_STIFFNESS}, "
          f"error {cal.stiffness_scale / TRUE_STIFFNESS - 1:+.1%}), tension scale "
          f"{cal.tension_scale:.3f} ± {cal.tension_scale_std:.3f} (true 1)")


if __name__ == "__main__":
    main()

"""The tests' small whole-unit calibration over several draws (issue 13).

`tests/calibration/test_whole_unit.py` specifies what held on every draw of its unit (2 x 2
bundles a layer, takes at 0.35 and 0.45 g, friction drawn with 10 % jitter and hidden, budget
150) and pins one written and one refused draw. This prints each draw's outcome, which its
docstring and docs/calibration.md summarise: written or refused (and why), simulations,
bundle-bundle's fitted coefficients against the truth, and, for a written fit, the third
level's prediction (the mean of its replays) and the share of them that reproduce it (the
take is one of two outcomes, and a few replays in the other swing the mean).

    python -m benchmarks.whole_unit_draws [--seed 0 1 2 3 4 5]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from tests.calibration.test_whole_unit import Draw


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, nargs="+", default=list(range(6)))
    args = parser.parse_args(argv)
    for seed in args.seed:
        with tempfile.TemporaryDirectory() as folder:
            draw = Draw(seed, Path(folder))
            result = draw.result
            pair = result.calibration.friction["bundle_bundle"]
            line = (f"seed {seed}: {'written' if result.converged else 'REFUSED'}, "
                    f"{result.simulations} simulations; bundle-bundle kinetic "
                    f"{pair.kinetic - draw.truth['kinetic']:+.3f} ± {pair.kinetic_std:.3f}, "
                    f"static {pair.static - draw.truth['static']:+.3f} ± "
                    f"{pair.static_std:.3f} (error ± std)")
            if result.converged:
                layer, check = draw.held_out()
                line += f"; third level, layer {layer}: {check.error_pct:+.0f} % by the mean"
                if check.reproduced is not None:
                    line += f" of its replays, {check.reproduced:.0%} of them within 15 %"
            else:
                line += (f"; the take {Path(result.verdict.source).name} left "
                         f"{1e3 * result.verdict.rms_m:.1f} mm unexplained")
            print(line, flush=True)


if __name__ == "__main__":
    main()

"""How reproducible the bench's verdict is: a unit against itself reflected, or renumbered.

A symmetric unit reflected in the plane y = 0 (every bundle at (x, -y)) is the same physics, and
so is the same unit with its bundles added in reverse order; only the order in which Bullet's
sequential solver visits the contacts changes. Any difference in the verdict is the model's own
resolution: what no cheaper fidelity (a larger step, fewer iterations, half a unit) can be held
below, and how far apart a margin must be to tell two wraps apart. Cases: bench_screening's 14
wrapped ones and four unwrapped ones, each run three ways, alternated. Printed per way: verdicts
that agree with the unit as laid out, the margin's difference (over the levels not decided
failed) and the largest permanent displacement's difference. `--rigid-boxes`: the same with
`SimSettings.rigid_boxes` (its pyramid of friction directions is symmetric in y too).

    taskset -c 0 python -m benchmarks.bench_reflection [--rigid-boxes]
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from dataclasses import replace

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from benchmarks.bench_screening import CASES, UNITS, Case, describe, wrap_of  # noqa: E402
from wrapenv.bench import SimSettings, run_level  # noqa: E402
from wrapenv.eumos import evaluate, level_margin  # noqa: E402
from wrapenv.load import Layout, LoadUnit  # noqa: E402
from wrapenv.profile import PulseProfile  # noqa: E402

#: A case without a wrap: (unit, None, level g).
Unwrapped = tuple[str, None, float]

UNWRAPPED: list[Unwrapped] = [("2L", None, 0.3), ("2L", None, 0.5), ("3L", None, 0.2),
                              ("3L", None, 0.3)]


def reflected(layout: Layout) -> Layout:
    """Every bundle at (x, -y): the same physics, the contacts met in another order."""
    return replace(layout, bundles=tuple(
        replace(b, centre_m=(b.centre_m[0], -b.centre_m[1], b.centre_m[2]))
        for b in layout.bundles))


def renumbered(layout: Layout) -> Layout:
    """The bundles added to the world in reverse order."""
    return replace(layout, bundles=layout.bundles[::-1])


WAYS: dict[str, Callable[[Layout], Layout]] = {
    "as laid out": lambda layout: layout, "reflected in y": reflected,
    "bundles in reverse order": renumbered}


def run(case: Case | Unwrapped, way: str, settings: SimSettings) -> tuple[bool, float, float]:
    """Passed, margin and largest permanent displacement of `case` laid out `way`."""
    unit, spec, level = case
    load = LoadUnit.from_toml(UNITS[unit])
    wrap = None if spec is None else wrap_of(spec, load.load_height_m)
    verdict = evaluate(run_level(WAYS[way](load.layout()), PulseProfile(level), settings, wrap))
    return (verdict.passed, level_margin(verdict, load.load_height_m),
            verdict.permanent_max_m or 0.0)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rigid-boxes", action="store_true",
                        help="run with SimSettings.rigid_boxes (not the bench's default)")
    args = parser.parse_args(argv)
    settings = SimSettings(rigid_boxes=args.rigid_boxes)
    cases = CASES + UNWRAPPED
    results: dict[str, list[tuple[bool, float, float]]] = {way: [] for way in WAYS}
    print(f"{len(cases)} cases; verdict, margin and permanent displacement of each way:")
    for case in cases:
        for way in WAYS:
            results[way].append(run(case, way, settings))
        name = describe(case) if case[1] is not None else f"{case[0]}, unwrapped, {case[2]} g"
        print(f"  {name:42s} " + " | ".join(
            f"{'pass' if p else 'FAIL'} {m:+.3f} {1000 * d:6.1f} mm"
            for p, m, d in (results[w][-1] for w in WAYS)), flush=True)
    base = results["as laid out"]
    print(f"\n{'against the unit as laid out':28s} {'verdicts agree':>14} "
          f"{'margin difference mean / max':>29} {'permanent difference max mm':>27}")
    for way in list(WAYS)[1:]:
        got = results[way]
        pairs = list(zip(got, base, strict=True))
        agree = sum(a[0] == b[0] for a, b in pairs)
        diff = np.array([abs(a[1] - b[1]) for a, b in pairs if a[1] > -1 and b[1] > -1])
        perm = max(abs(a[2] - b[2]) for a, b in pairs)
        text = f"{diff.mean():.3f} / {diff.max():.3f}" if len(diff) else "-"
        print(f"{way:28s} {agree:>7d} of {len(base):<4d} {text:>29} {1000 * perm:27.1f}")


if __name__ == "__main__":
    main()

"""Where a policy's proposals stand between training's test and `recommend`'s verification.

Training tests a proposal on one side (the pallet's long side along the motion), freshly
wrapped, at the target level alone, at the unit's nominal values, with no margin asked.
`recommend --method ppo` verifies it on both sides, 16 h after wrapping, through the EUMOS
sequence up to the target, in samples of what the bench does not know, with a margin of 0.2.
This runs the policy's proposals for held-out units through the tests in between, one
difference at a time, at nominal values (no samples), so that what separates the two tests can
be read off (each side a unit of its own, as `recommend` tests it):

    python benchmarks/policy_tests.py --policy RUN/policy.zip [--material kraft|lldpe]
                                      [--held-out 60] [--target 0.5]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from recommender.policy import held_out_loads, load_policy, propose
from wrapenv.bench import SimSettings, run_levels
from wrapenv.load import LoadUnit, Orientation
from wrapenv.profile import eumos_levels
from wrapenv.uncertainty import TRANSPORT_HOURS
from wrapenv.wrap import WrapFormat

#: The margin `recommend` asks of its worst sample (`recommender.problem.Problem.margin_goal`).
MARGIN_GOAL = 0.2
#: (name, sides, relaxed 16 h, the sequence up to the target rather than the target alone)
TESTS: list[tuple[str, tuple[Orientation, ...], bool, bool]] = [
    ("long side, fresh, target alone (training's test)", ("long",), False, False),
    ("long side, fresh, the sequence", ("long",), False, True),
    ("long side, relaxed, target alone", ("long",), True, False),
    ("short side, fresh, target alone", ("short",), False, False),
    ("long side, relaxed, the sequence", ("long",), True, True),
    ("short side, relaxed, the sequence", ("short",), True, True),
    ("both sides, relaxed, the sequence", ("long", "short"), True, True),
]


def tested(load: LoadUnit, wrap: WrapFormat, target_g: float, side: Orientation,
           relaxed: bool, sequence: bool) -> tuple[bool, float]:
    """Whether the unit passed on this side, and its margin."""
    levels = eumos_levels(target_g) if sequence else [target_g]
    laid = wrap.relaxed(TRANSPORT_HOURS) if relaxed else wrap
    run = run_levels(load, levels, SimSettings(), orientation=side, stop_at_failure=True,
                     wrap=laid)
    return run.verdict.passed, float(run.verdict.margin)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", type=Path, required=True)
    parser.add_argument("--material", default="kraft", choices=("kraft", "lldpe"))
    parser.add_argument("--held-out", type=int, default=60)
    parser.add_argument("--target", type=float, default=0.5)
    args = parser.parse_args()
    model = load_policy(args.policy, args.material)
    loads = held_out_loads(args.held_out, seed=0)
    wraps = [propose(model, load, args.material, args.target) for load in loads]
    n = len(loads)
    #: per (side, relaxed, sequence), each unit's result: a side shared by two tests runs once
    by_side: dict[tuple[Orientation, bool, bool], list[tuple[bool, float]]] = {}
    for name, sides, relaxed, sequence in TESTS:
        t0 = time.perf_counter()
        for side in sides:
            if (side, relaxed, sequence) not in by_side:
                by_side[side, relaxed, sequence] = [
                    tested(load, wrap, args.target, side, relaxed, sequence)
                    for load, wrap in zip(loads, wraps, strict=True)]
        per_unit = zip(*(by_side[side, relaxed, sequence] for side in sides), strict=True)
        results = [(all(p for p, _ in r), min(m for _, m in r)) for r in per_unit]
        passed = sum(p for p, _ in results)
        kept = sum(p and m >= MARGIN_GOAL for p, m in results)
        print(f"{name:50s} passed {passed:3d}/{n}, with a margin >= {MARGIN_GOAL:g} {kept:3d}/{n}"
              f" ({time.perf_counter() - t0:.0f} s)", flush=True)

if __name__ == "__main__":
    main()

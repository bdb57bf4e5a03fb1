"""Where a policy's proposals stand between training's nominal test and `recommend`'s verification.

Training's nominal test (`wrapbench train --test nominal`) tests a proposal on one side (the
pallet's long side along the motion), freshly wrapped, at the target level alone, at the unit's
nominal values, with no margin asked.
`recommend --method ppo` verifies it on both sides, 16 h after wrapping, through the EUMOS
sequence up to the target, in samples of what the bench does not know, with a margin of 0.2.
This runs the policy's proposals for held-out units through the tests in between, one
difference at a time, at nominal values (no samples), so that what separates the two tests can
be read off (each side a unit of its own, as `recommend` tests it), and last through the
verification itself (`recommender.search.verify`, as `recommend --method ppo` runs it: a
proposal holds when it passes both nominal sequences and every one of 8 samples):

    python -m benchmarks.policy_tests --policy RUN/policy.zip [--material kraft|lldpe]
                                      [--held-out 60] [--target 0.5]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from recommender.policy import held_out_loads, load_policy, propose
from recommender.problem import Problem, SearchSettings
from recommender.search import verify
from wrapenv.bench import SimSettings, run_levels
from wrapenv.load import LoadUnit, Orientation
from wrapenv.profile import eumos_levels
from wrapenv.uncertainty import TRANSPORT_HOURS
from wrapenv.wrap import Web, WrapFormat

#: The margin `recommend` asks of its worst sample (`recommender.problem.Problem.margin_goal`).
MARGIN_GOAL = 0.2
#: Samples `recommend --method ppo` verifies a proposal in (its `max(8, --samples)`).
VERIFY_SAMPLES = 8
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


def verified(load: LoadUnit, wrap: WrapFormat, material: str, target_g: float,
             workers: int) -> tuple[bool, float]:
    """Whether the proposal holds `recommend --method ppo`'s verification, and the smallest
    margin of its nominal sequences and its worst sample."""
    settings = SearchSettings(targets=(("long", target_g), ("short", target_g)),
                              web=Web.named(material), workers=workers)
    check = verify(Problem.build(load, settings), wrap, VERIFY_SAMPLES, workers)
    margins = [run.verdict.margin for run in check.runs.values()]
    if check.worst is not None:
        margins.append(check.worst.margin)
    return check.holds, float(min(margins))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", type=Path, required=True)
    parser.add_argument("--material", default="kraft", choices=("kraft", "lldpe"))
    parser.add_argument("--held-out", type=int, default=60)
    parser.add_argument("--target", type=float, default=0.5)
    parser.add_argument("--workers", type=int, default=2,
                        help="processes the verification's runs share (the rows above run in one)")
    args = parser.parse_args()
    model = load_policy(args.policy, args.material)
    loads = held_out_loads(args.held_out, seed=0)
    wraps = [propose(model, load, args.material, args.target) for load in loads]
    web_kg = [w.material_used_on(load.layout()).mass_kg for load, w in zip(loads, wraps,
                                                                            strict=True)]
    print(f"the policy's {len(wraps)} proposals lay {sum(web_kg) / len(web_kg):.3f} kg of web "
          f"on average ({min(web_kg):.3f}-{max(web_kg):.3f})", flush=True)
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
        report(name, results, time.perf_counter() - t0)
    t0 = time.perf_counter()
    results = [verified(load, wrap, args.material, args.target, args.workers)
               for load, wrap in zip(loads, wraps, strict=True)]
    report(f"the verification ({VERIFY_SAMPLES} samples as well)", results,
           time.perf_counter() - t0)


def report(name: str, results: list[tuple[bool, float]], seconds: float) -> None:
    n = len(results)
    passed = sum(p for p, _ in results)
    kept = sum(p and m >= MARGIN_GOAL for p, m in results)
    print(f"{name:50s} passed {passed:3d}/{n}, with a margin >= {MARGIN_GOAL:g} {kept:3d}/{n}"
          f" ({seconds:.0f} s)", flush=True)

if __name__ == "__main__":
    main()

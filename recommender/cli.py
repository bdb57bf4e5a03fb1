"""`wrapbench`: the command line of the virtual bench.

Exit status (CONTRACTS.md): 0 success; 1 the run completed but the load failed the asked test;
2 bad input or usage, with one line on stderr naming the file and the field.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

from tqdm import tqdm

from calibration import commands
from recommender.parallel import BACKENDS
from wrapenv.bench import BenchRun, run_levels
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, check_output, write_atomic
from wrapenv.eumos import LevelVerdict
from wrapenv.load import Layout, LoadUnit
from wrapenv.profile import MeasuredProfile, PulseProfile, eumos_levels
from wrapenv.wrap import MATERIALS, WrapFormat

#: Robust passes tried, lightest first, until one passes the whole EUMOS sequence.
VERIFY_CANDIDATES = 3
#: The bundled example (a link to examples/pet_2layer_columnar.toml, copied into wheels).
EXAMPLE_LOAD = Path(__file__).resolve().parent / "data" / "example_load.toml"


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line and exits with status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        sys.exit(2)


def _g(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="wrapbench", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sim = sub.add_parser("simulate", help="run a load unit on the virtual ESTL bench")
    sim.add_argument("load", type=Path, help="LOAD.toml")
    sim.add_argument("--wrap", type=Path, metavar="WRAP.toml",
                     help="wrap the unit in this format (default: unwrapped)")
    sim.add_argument("--calibration", type=Path,
                     help="CAL.json with fitted friction (and wrap stiffness and tension scales)")
    sim.add_argument("--level", type=_g, action="append", metavar="G",
                     help="test level in g (repeatable)")
    sim.add_argument("--eumos", action="store_true",
                     help="EUMOS sequence from --start up to --target, stopping at the first "
                          "failure (the default when no level or profile is given)")
    sim.add_argument("--target", type=_g, default=0.5, metavar="G", help="default 0.5 g")
    sim.add_argument("--start", type=_g, default=0.2, metavar="G", help="default 0.2 g")
    sim.add_argument("--profile", type=Path, help="drive the sled by a measured profile.csv")
    sim.add_argument("--orientation", choices=("long", "short"),
                     help="pallet side along the motion (default: as the load file lays it out)")
    sim.add_argument("--json", type=Path, metavar="OUT", help="write the verdict as JSON")
    sim.add_argument("--plot", type=Path, metavar="OUT.png", help="plot displacement vs time")

    rec = sub.add_parser("recommend", help="search the wrap format with the least material that "
                                           "passes EUMOS 40509 up to the target")
    rec.add_argument("load", type=Path, nargs="?", default=EXAMPLE_LOAD,
                     help="LOAD.toml (default: the bundled 2-layer example)")
    rec.add_argument("--calibration", type=Path, help="CAL.json (friction and its uncertainty)")
    rec.add_argument("--material", default="kraft", help="kraft (default) or lldpe")
    rec.add_argument("--target", type=_g, default=0.5, metavar="G", help="default 0.5 g")
    rec.add_argument("--method", choices=("cmaes", "ppo"), default="cmaes",
                     help="cmaes: robust search (default); ppo: a trained policy's proposal, "
                          "verified in simulation (needs --policy)")
    rec.add_argument("--policy", type=Path, metavar="FILE",
                     help="policy.zip written by `wrapbench train` (with --method ppo)")
    rec.add_argument("--samples", type=int, default=3, metavar="K",
                     help="robust samples of friction and masses per candidate (default 3)")
    rec.add_argument("--margin", type=float, default=0.2,
                     help="wanted EUMOS margin of the worst sample (default 0.2)")
    rec.add_argument("--budget", type=int, default=48, metavar="N",
                     help="most candidate formats to try (default 48)")
    rec.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                     help="parallel simulations (default: all cores)")
    rec.add_argument("--backend", choices=BACKENDS, default="process",
                     help="where simulations run: worker processes here (default) or Ray "
                          "(needs `pip install .[ray]`)")
    rec.add_argument("--ray-address", metavar="ADDRESS",
                     help="with --backend ray: join this cluster ('auto', 'ray://host:10001'); "
                          "default: start a local Ray instance of --workers CPUs")
    rec.add_argument("--seed", type=int, default=0)
    rec.add_argument("--checkpoint", type=Path, default=Path("wrapbench-search.ckpt"),
                     help="search state written after every generation (default "
                          "wrapbench-search.ckpt; removed when the search ends)")
    rec.add_argument("--resume", action="store_true", help="continue from --checkpoint")
    rec.add_argument("--json", type=Path, metavar="OUT", help="write the result as JSON")
    rec.add_argument("--wrap-out", type=Path, metavar="WRAP.toml",
                     help="write the recommended format as a WRAP.toml")
    rec.add_argument("--report", type=Path, metavar="DIR",
                     help="write displacement.png, search.png and test.mp4 (the recommended "
                          "format's test at the target level) into DIR")

    tr = sub.add_parser("train", help="train a PPO policy on random load units "
                                      "(wrapenv/WrapBenchRandom-v0)")
    tr.add_argument("--out", type=Path, required=True, metavar="DIR",
                    help="folder for policy.zip, checkpoints/ and log.csv")
    tr.add_argument("--timesteps", type=int, default=2048)
    tr.add_argument("--envs", type=int, default=os.cpu_count() or 1,
                    help="parallel environments (default: all cores)")
    tr.add_argument("--material", default="kraft")
    tr.add_argument("--target", type=_g, default=0.5, metavar="G")
    tr.add_argument("--seed", type=int, default=0)

    commands.add_synth(sub, _g)
    commands.add_track(sub)
    commands.add_calibrate(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        command = {"simulate": _simulate, "recommend": _recommend, "train": _train,
                   "synth": commands.run_synth, "track": commands.run_track,
                   "calibrate": commands.run_calibrate}
        return command[args.command](args)
    except InputError as exc:
        sys.stderr.write(f"wrapbench {args.command}: {exc}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write(f"wrapbench {args.command}: interrupted, nothing written\n")
        return 130


def _target(target_g: float) -> None:
    """A target level the bench can produce, or a usage error naming --target."""
    try:
        PulseProfile(target_g)
    except InputError as exc:
        raise InputError("arguments", "--target", exc.message) from None


def _level(level_g: float) -> PulseProfile:
    try:
        return PulseProfile(level_g)
    except InputError as exc:
        raise InputError("arguments", "--level", exc.message) from None


def _simulate(args: argparse.Namespace) -> int:
    load = LoadUnit.from_toml(args.load)
    wrap = WrapFormat.from_toml(args.wrap, load.load_height_m) if args.wrap else None
    if args.calibration:
        calibration = Calibration.from_json(args.calibration)
        load = calibration.apply(load)
        if wrap is not None:
            wrap = wrap.scaled(calibration.stiffness_scale, calibration.tension_scale)
    check_output(args.json, "--json")
    check_output(args.plot, "--plot")
    if args.profile and (args.level or args.eumos):
        raise InputError("arguments", "--profile", "cannot be combined with --level or --eumos")
    if args.level and args.eumos:
        raise InputError("arguments", "--level", "cannot be combined with --eumos")
    if args.profile:
        levels: list = [MeasuredProfile.from_csv(args.profile)]
    elif args.level:
        levels = [_level(g) for g in args.level]  # validates every level before running
    else:
        levels = [PulseProfile(g) for g in eumos_levels(args.target, args.start)]
    stop = not args.level and not args.profile
    run = run_levels(load, levels, orientation=args.orientation, stop_at_failure=stop, wrap=wrap)
    layout = load.layout(args.orientation)
    print(_table(load, run, args.orientation))
    if wrap is not None:
        print(_wrap_summary(wrap, layout))
    if args.json:
        out = run.verdict.to_json()
        if wrap is not None:
            out["format"] = wrap.to_dict()
            out["material_used"] = asdict(wrap.material_used_on(layout))
            out["recipe"] = wrap.machine_recipe().to_json()
        write_atomic(args.json, (json.dumps(out, indent=2) + "\n").encode())
    if args.plot:
        from recommender.report import plot_displacements

        plot_displacements(run, args.plot, title=load.name)
    return 0 if run.verdict.passed else 1


def _wrap_summary(wrap: WrapFormat, layout: Layout) -> str:
    used = wrap.material_used_on(layout)
    lines = [f"wrap: {wrap.material.name}, web {wrap.web_width_m:.2f} m, {len(wrap.bands)} bands;"
             f" material used {used.area_m2:.2f} m² ({used.mass_kg:.3f} kg, {used.length_m:.1f} m"
             " of web)",
             wrap.machine_recipe().table()]
    return "\n".join(lines)


def _train(args: argparse.Namespace) -> int:
    from recommender.policy import TrainSettings, train

    for flag, value in (("--timesteps", args.timesteps), ("--envs", args.envs)):
        if value < 1:
            raise InputError("arguments", flag, f"must be >= 1 (got {value})")
    if args.material not in MATERIALS:
        raise InputError("arguments", "--material",
                         f"must be one of {', '.join(map(repr, MATERIALS))} "
                         f"(got {args.material!r})")
    _target(args.target)
    if args.out.exists() and not args.out.is_dir():
        raise InputError(str(args.out), "--out", "exists and is not a folder")
    args.out.mkdir(parents=True, exist_ok=True)
    settings = TrainSettings(timesteps=args.timesteps, n_envs=args.envs, material=args.material,
                             target_g=args.target, seed=args.seed)
    path = train(settings, args.out)
    print(f"policy written to {path} (log: {args.out / 'log.csv'})")
    return 0


def _propose_with_policy(args: argparse.Namespace, problem, verify) -> tuple:
    """A trained policy's format for this unit, answered at once, then verified."""
    from recommender.policy import propose
    from recommender.search import Evaluation

    if args.policy is None or not args.policy.is_file():
        where = "arguments" if args.policy is None else str(args.policy)
        raise InputError(where, "--policy", "a policy.zip from `wrapbench train` is needed "
                                            "with --method ppo")
    calibration = Calibration.from_json(args.calibration) if args.calibration else None
    wrap = propose(args.policy, LoadUnit.from_toml(args.load), args.material, args.target,
                   calibration)
    run, rate = verify(problem, wrap, max(8, args.samples), workers=args.workers)
    mass = wrap.material_used_on(problem.layout).mass_kg
    best = Evaluation((), wrap, mass, (run.verdict.margin,), (run.verdict.passed,), 0.0)
    return run, rate, best


def _recommend(args: argparse.Namespace) -> int:
    from recommender.search import Problem, RobustSearch, SearchSettings, verify

    load = LoadUnit.from_toml(args.load)
    calibration = Calibration.from_json(args.calibration) if args.calibration else None
    for flag, value, low in (("--samples", args.samples, 1), ("--budget", args.budget, 2),
                             ("--workers", args.workers, 1)):
        if value < low:
            raise InputError("arguments", flag, f"must be >= {low} (got {value})")
    if not (math.isfinite(args.margin) and 0 <= args.margin < 1):
        raise InputError("arguments", "--margin", f"must be in [0, 1) (got {args.margin})")
    check_output(args.json, "--json")
    check_output(args.wrap_out, "--wrap-out")
    check_output(args.checkpoint, "--checkpoint")
    if args.report is not None and args.report.exists() and not args.report.is_dir():
        raise InputError(str(args.report), "--report", "exists and is not a folder")
    settings = SearchSettings(target_g=args.target, material=args.material,
                              samples=args.samples, margin_goal=args.margin,
                              max_candidates=args.budget, seed=args.seed, workers=args.workers,
                              popsize=min(8, args.budget), backend=args.backend,
                              ray_address=args.ray_address)
    _target(args.target)
    problem = Problem.build(load, settings, calibration)
    if args.method == "ppo":
        t0 = time.perf_counter()
        run, rate, best = _propose_with_policy(args, problem, verify)
        print(_recommendation(load, best, rate, max(8, args.samples), args.target))
        print(_table(problem.load, run, None))
        print(_wrap_summary(best.wrap, problem.layout))
        print(f"policy proposal verified in {time.perf_counter() - t0:.0f} s")
        _write_outputs(args, problem.layout, best, run, rate, max(8, args.samples), 1)
        return 0 if run.verdict.passed else 1
    search = RobustSearch(problem, args.checkpoint)
    state = search.resume() if args.resume else search.start()
    t0 = time.perf_counter()
    with tqdm(total=settings.max_candidates, desc="candidates", unit="format",
              file=sys.stderr, disable=None) as bar:
        bar.update(len(state.history))

        def progress(done: int, total: int, st) -> None:
            bar.update(done - bar.n)
            best = st.best(settings.margin_goal)
            if best is not None:
                bar.set_postfix(best_kg=f"{best.mass_kg:.3f}", margin=f"{best.margin:.2f}")

        state = search.run(state, progress)
    verdict_samples = max(8, args.samples)
    chosen = None
    for candidate in state.ranked(settings.margin_goal)[:VERIFY_CANDIDATES]:
        # the search tried the target level; the recommendation must pass the whole sequence
        run, rate = verify(problem, candidate.wrap, verdict_samples, workers=args.workers)
        if run.verdict.passed:
            chosen, best = (run, rate), candidate
            break
    args.checkpoint.unlink(missing_ok=True)
    if chosen is None:
        print(f"no format passed the EUMOS sequence up to {args.target:.2f} g after "
              f"{len(state.history)} candidates x {args.samples} samples")
        return 1
    run, rate = chosen
    layout = problem.layout
    print(_recommendation(load, best, rate, verdict_samples, args.target))
    print(_table(problem.load, run, None))
    print(_wrap_summary(best.wrap, layout))
    print(f"searched {len(state.history)} candidates x {args.samples} samples in "
          f"{time.perf_counter() - t0:.0f} s ({args.workers} workers, {args.backend})")
    _write_outputs(args, layout, best, run, rate, verdict_samples,
                   len(state.history) * args.samples, candidates=len(state.history))
    if args.report:
        _write_report(args.report, problem, run, best, state, settings.margin_goal)
    return 0


def _write_outputs(args: argparse.Namespace, layout: Layout, best, run: BenchRun, rate: float,
                   samples: int, evaluations: int, candidates: int | None = None) -> None:
    if args.json:
        used = best.wrap.material_used_on(layout)
        out = {"format": best.wrap.to_dict(), "material_used": asdict(used),
               "verdict": run.verdict.to_json(), "robust_pass_rate": rate,
               "robust_samples": samples, "search_margin": best.margin,
               "evaluations": evaluations, "candidates": candidates,
               "method": args.method, "target_g": args.target}
        write_atomic(args.json, (json.dumps(out, indent=2) + "\n").encode())
    if args.wrap_out:
        write_atomic(args.wrap_out, best.wrap.to_toml().encode())


def _write_report(folder: Path, problem, run: BenchRun, best, state, margin_goal: float) -> None:
    from recommender.report import plot_displacements, plot_search, write_video

    folder.mkdir(parents=True, exist_ok=True)
    plot_displacements(run, folder / "displacement.png", title=problem.load.name)
    plot_search(state.history, best, folder / "search.png", margin_goal)
    write_video(run.traces[-1], problem.layout, problem.simulated(best.wrap),
                folder / "test.mp4")


def _recommendation(load: LoadUnit, best, rate: float, samples: int, target_g: float) -> str:
    lines = [f"recommended wrap for {load.name}: passes {target_g:.2f} g in {rate:.0%} of "
             f"{samples} samples of friction and mass (search margin {best.margin:.2f})",
             "band  from m    to m  layers  tension N"]
    for i, b in enumerate(sorted(best.wrap.bands, key=lambda b: b.from_m), start=1):
        lines.append(f"{i:4d}  {b.from_m:6.3f}  {b.to_m:6.3f}  {b.layers:6d}  {b.tension_n:9.1f}")
    return "\n".join(lines)


def _mm(x: float | None) -> str:
    return "   n/a" if x is None else f"{x * 1000:6.1f}"


def _row(v: LevelVerdict) -> str:
    result = "PASS" if v.passed else ("INVALID" if not v.valid else "FAIL")
    failed = [k for k, ok in v.criteria.items() if not ok]
    note = v.invalid_reason or (", ".join(failed) if failed else "")
    damage = f"; {len(v.damage)} damaged: {', '.join(v.damage[:4])}" if v.damage else ""
    if len(v.damage) > 4:
        damage += ", ..."
    return (f"{v.level_g:5.2f} g  {result:7s} {_mm(v.elastic_max_m)} mm "
            f"({v.elastic_max_pct or 0:5.1f} %)"
            f"  {_mm(v.permanent_max_m)} mm ({v.permanent_max_pct or 0:5.1f} %)"
            f"  {_mm(v.permanent_low20_m)} mm  {_mm(v.pallet_slip_m)} mm  {note}{damage}")


def _table(load: LoadUnit, run: BenchRun, orientation: str | None) -> str:
    layout = load.layout(orientation)  # type: ignore[arg-type]
    v = run.verdict
    lines = [
        f"{load.name}: {len(layout.bundles)} bundles, {load.stack.layers} layers "
        f"({load.stack.pattern}), load height {v.load_height_m:.3f} m, {load.mass_kg:.0f} kg",
        f"EUMOS 40509 limits: elastic <= {100 * v.load_height_m:.1f} mm, permanent <= "
        f"{50 * v.load_height_m:.1f} mm, lowest 20 cm < 40 mm, no damage",
        "level    result    elastic max            permanent max       low 20 cm  pallet slip",
    ]
    lines += [_row(level) for level in v.levels]
    torn = [f"{level.level_g:.2f} g" for level in v.levels if level.wrap and level.wrap.torn]
    if torn:
        lines.append(f"wrap torn at: {', '.join(torn)}")
    best = v.highest_passed_g
    lines.append(f"highest level passed: {'none' if best is None else f'{best:.2f} g'}"
                 + ("" if v.valid else "  (simulation became unphysical: see INVALID rows)"))
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())

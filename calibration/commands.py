"""`wrapbench synth`, `track` and `calibrate`: the recording side of the command line.

`recommender.cli` owns the `wrapbench` parser and registers these subcommands; their options and
output live here, beside the code they drive. Errors of input are `InputError`s, which the CLI
turns into one line and exit status 2.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from wrapenv.calibrated import DEFAULT_MAX_RESIDUAL_M
from wrapenv.config import (
    InputError,
    check_checkpoint,
    check_distinct,
    check_output,
    printable,
    result_json,
    shown_path,
    write_together,
)
from wrapenv.load import Friction, LoadUnit
from wrapenv.pool import most_workers
from wrapenv.profile import g_text, profile_warnings
from wrapenv.wrap import WrapFormat

if TYPE_CHECKING:   # imported where used: the CLI starts without the fitting's modules
    from calibration.fit import FitResult, FitSettings
    from calibration.validate import Check, Validation

#: Longest message printed whole (it may quote a recording's folder, which `printable` makes safe).
MESSAGE_CHARS = 2000
#: `synthesize`'s arguments, as its errors name them (source, field), and the flags that set
#: them.
SYNTH_FLAGS = {("arguments", "size"): "--size", ("arguments", "fps"): "--fps",
               ("arguments", "friction_jitter"): "--friction-jitter",
               ("arguments", "levels_before_g"): "--levels-before",
               ("profile", "level_g"): "--level"}


def level_g(text: str) -> float:
    """argparse's type for a test level in g; its errors name the value expected (argparse
    would print "invalid <this function's name> value" for a bare ValueError)."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a level in g such as 0.4 (got {text!r})")
    return value


#: The largest seed: pycma (given seed + 1, since it reads 0 as "seed from the clock") takes
#: 32-bit seeds only.
MAX_SEED = 2**32 - 2


def seed(text: str) -> int:
    """argparse's type for a seed: a whole number from 0 to `MAX_SEED` (numpy's generators take
    no negative one)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"expected a whole number from 0 to {MAX_SEED} "
                                         f"(got {text!r})")
    return value


def add_synth(sub: argparse._SubParsersAction) -> None:
    """The synth subcommand."""
    p = sub.add_parser("synth", help="make a synthetic bench recording with ground truth")
    p.add_argument("load", type=Path, help="LOAD.toml")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="recording folder to create (must not exist or be empty)")
    p.add_argument("--wrap", type=Path, metavar="WRAP.toml", help="wrap the unit in this format")
    p.add_argument("--level", type=level_g, default=0.4, metavar="G",
                   help="test level in g (default 0.4)")
    p.add_argument("--levels-before", type=level_g, nargs="+", default=[], metavar="G",
                   help="levels the unit runs first, unfilmed, as a lab runs one unit through "
                        "the EUMOS levels (setup.toml's recording.levels_before_g)")
    p.add_argument("--seed", type=seed, default=0,
                   help="textures, noise and the friction jitter's draw (takes of one unit at "
                        "several levels share it)")
    p.add_argument("--size", type=_size, default=(1920, 1200), metavar="WxH",
                   help="image size in pixels (default 1920x1200)")
    p.add_argument("--fps", type=float, default=20.0, help="frames per second (default 20)")
    p.add_argument("--friction-jitter", type=float, default=0.0, metavar="J",
                   help="draw each pair's true friction from the load's value x U(1-J, 1+J)")
    p.add_argument("--stiffness-scale", type=float, default=1.0,
                   help="true wrap stiffness relative to the material card (default 1)")
    p.add_argument("--tension-scale", type=float, default=1.0,
                   help="true wrap tension relative to WRAP.toml (default 1)")


def add_track(sub: argparse._SubParsersAction) -> None:
    from calibration.track import DEFAULT_TRACKER
    from calibration.vision.tracking import OPENCV_TRACKERS, OWN_TRACKERS

    p = sub.add_parser("track", help="object trajectories from a bench recording")
    p.add_argument("recording", type=Path, metavar="DIR", help="recording folder")
    p.add_argument("--out", type=Path, metavar="trajectories.csv",
                   help="trajectories CSV (default DIR/trajectories.csv)")
    p.add_argument("--debug-video", type=Path, metavar="OUT.mp4",
                   help="the recording with boxes, ids and centres drawn")
    p.add_argument("--tracker", choices=OWN_TRACKERS + OPENCV_TRACKERS, default=DEFAULT_TRACKER,
                   help=f"how objects are followed (default {DEFAULT_TRACKER})")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH, e.g. 1920x1200 (got {text!r})") from None
    return w, h


@contextmanager
def _frame_bar() -> Iterator[Callable[[int, int], None]]:
    """A progress bar of frames on stderr (none when stderr is not a terminal), fed by a
    `progress(frame, frames)` callback."""
    with tqdm(desc="frames", unit="frame", leave=False, disable=None) as bar:
        def progress(frame: int, frames: int) -> None:
            bar.total = frames
            bar.update(frame - bar.n)

        yield progress


def _levels_text(levels_g: tuple[float, ...]) -> str:
    return ", ".join(g_text(g) for g in levels_g) + " g"


def _after_levels(levels_g: tuple[float, ...]) -> str:
    return f" (after {_levels_text(levels_g)})" if levels_g else ""


def _replayed_after(levels_g: tuple[float, ...]) -> str:
    """What a calibration's replays of a take run first (setup.toml's levels_before_g)."""
    return (f"; replayed after the levels its unit ran before it, {_levels_text(levels_g)}"
            if levels_g else "")


def run_synth(args: argparse.Namespace) -> int:
    from calibration.synth import marker_warning, synthesize

    load = LoadUnit.from_toml(args.load)
    wrap = WrapFormat.from_toml(args.wrap, load.load_height_m) if args.wrap else None
    for flag, value in (("--stiffness-scale", args.stiffness_scale),
                        ("--tension-scale", args.tension_scale)):
        if not (math.isfinite(value) and value > 0):
            raise InputError("arguments", flag, f"must be > 0 (got {value})")
        if wrap is None and value != 1.0:
            raise InputError("arguments", flag, "needs --wrap (an unwrapped unit has no web "
                             f"to scale; got {value:g})")
    t0 = time.perf_counter()
    try:
        with _frame_bar() as progress:
            rec = synthesize(load, args.out, wrap=wrap, level_g=args.level, seed=args.seed,
                             size=args.size, fps=args.fps, friction_jitter=args.friction_jitter,
                             stiffness_scale=args.stiffness_scale,
                             tension_scale=args.tension_scale,
                             levels_before_g=tuple(args.levels_before), progress=progress)
    except InputError as exc:
        option = SYNTH_FLAGS.get((exc.source, exc.field))
        if option is None:
            raise
        raise InputError("arguments", option, exc.message) from None
    except ValueError as exc:  # an unphysical simulation: nothing to record
        sys.stderr.write(f"wrapbench synth: {exc}; no recording written\n")
        return 1
    if warning := marker_warning(rec, args.size):
        sys.stderr.write(f"wrapbench synth: warning: {warning}\n")
    frames = round(rec.profile.t_s[-1] * rec.fps) + 1
    print(f"wrote {shown_path(rec.folder)}: {rec.video.name} {args.size[0]}x{args.size[1]}, "
          f"{frames} frames at {rec.fps:g} fps, {rec.px_per_m:g} px/m, level {g_text(args.level)} g"
          f"{_after_levels(rec.levels_before_g)}{', wrapped' if wrap else ''}, in "
          f"{time.perf_counter() - t0:.0f} s")
    return 0


def run_track(args: argparse.Namespace) -> int:
    from calibration.recording import TRUTH, Recording, Truth
    from calibration.track import track
    from calibration.trajectories import error_vs_truth

    rec = Recording.read(args.recording)
    out = args.out if args.out is not None else rec.folder / "trajectories.csv"
    check_output(out, "--out", inputs=rec.inputs())
    check_output(args.debug_video, "--debug-video", inputs=rec.inputs())
    check_distinct({"--out": out, "--debug-video": args.debug_video})
    truth = Truth.read(rec.folder) if (rec.folder / TRUTH).exists() else None
    t0 = time.perf_counter()
    with _frame_bar() as progress:
        result = track(rec, tracker=args.tracker, debug_video=args.debug_video,
                       progress=progress)
    wall = time.perf_counter() - t0
    result.trajectories.to_csv(out)
    for warning in result.warnings:
        sys.stderr.write(f"wrapbench track: warning: {warning}\n")
    objects = result.trajectories.objects
    frames = max((len(p.t_s) for p in objects.values()), default=0)
    print(f"wrote {shown_path(out)}: {len(objects)} objects ({', '.join(objects)}), "
          f"{frames} frames in {wall:.1f} s ({frames / wall:.0f} frames/s, tracker {args.tracker})")
    if args.debug_video is not None:
        print(f"wrote {shown_path(args.debug_video)}: the frames with every object as tracked")
    if truth is not None:
        errors = error_vs_truth(result.trajectories, truth.objects)
        print("error against truth.json (displacement):  object  RMS mm  max mm")
        for name, e in errors.items():
            print(f"{name:>44s}  {1e3 * e.rms_m:6.2f}  {1e3 * e.max_m:6.2f}")
    return 0


def add_calibrate(sub: argparse._SubParsersAction) -> None:
    from calibration.fit import METHODS, PARAMS

    p = sub.add_parser("calibrate", help="fit friction (and wrap) parameters to recordings")
    p.add_argument("recordings", type=Path, nargs="+", metavar="DIR",
                   help="recording folders of one load unit (several levels are fitted jointly)")
    p.add_argument("--out", type=Path, required=True, metavar="CAL.json",
                   help="fitted values; CAL-loss.png and CAL-overlay.png are written beside it")
    p.add_argument("--method", choices=METHODS, default="surrogate",
                   help="surrogate (default: the bench's mean response, for whole units), "
                        "cmaes or momentum (the source paper's gradient descent) on single "
                        "replays")
    p.add_argument("--params", choices=PARAMS, default="all",
                   help="friction, wrap (the web's stiffness and tension scales and the "
                        "load's give) or all (default)")
    p.add_argument("--budget", type=int, metavar="N",
                   help="most simulations of the fit's search and final replays (default "
                        "300, or where the recordings would share them so thinly that the "
                        "friction search gets one local stage or none, as five do, the least "
                        "that gives it all); a static coefficient it would report resolved is "
                        "probed on top, "
                        "12 replays per bare recording, up to 24 when the other values are "
                        "refitted; a recording the final replays, or a probe's, leave "
                        "unexplained is replayed up to 24 times in all before it is judged")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="parallel simulations (default: all cores)")
    p.add_argument("--seed", type=seed, default=0,
                   help="seed of the fit's designs and replays (same seed, same CAL.json)")
    p.add_argument("--max-residual-mm", type=float, default=1e3 * DEFAULT_MAX_RESIDUAL_M,
                   metavar="MM",
                   help="fail (nothing written) when more residual RMS than this is left "
                        "beyond the bench's own run-to-run scatter")
    p.add_argument("--validate", type=Path, nargs="+", default=[], metavar="DIR",
                   help="recordings not fitted: replay them with the calibrated bench and "
                        "report the prediction error per object (in CAL.json too)")
    p.add_argument("--mixed-loads", action="store_true",
                   help="accept recordings of different load units (their pairs fitted jointly)")
    p.add_argument("--known", nargs="+", default=[], metavar="NAME=SCALE",
                   help="wrap scales measured elsewhere, held instead of fitted: stiffness (the "
                        "web's, against its material card), tension (laid, against WRAP.toml) "
                        "or give (the load's edges, against LOAD.toml), e.g. tension=1 give=0.8")
    p.add_argument("--retrack", action="store_true",
                   help="track every recording even where DIR/trajectories.csv exists")
    p.add_argument("--checkpoint", type=Path, metavar="FILE",
                   help="keep the search's replays here as they finish (default: beside "
                        "--out, CAL.checkpoint.jsonl); removed when the fit ends")
    p.add_argument("--resume", action="store_true",
                   help="continue an interrupted fit: the replays its checkpoint holds are "
                        "not simulated again (same recordings and flags, same CAL.json)")


def _same_unit(load: LoadUnit) -> LoadUnit:
    """A load without its friction: the starting values may differ between recordings."""
    return load.with_friction(Friction())


def _recordings(args: argparse.Namespace) -> tuple[list, list]:
    """The recordings to fit and to validate on, all of one load unit unless --mixed-loads."""
    from calibration.recording import Recording

    fitted = [Recording.read(d) for d in args.recordings]
    held_out = [Recording.read(d) for d in args.validate]
    first = fitted[0]
    for rec in fitted[1:] + held_out:
        if not args.mixed_loads and _same_unit(rec.load) != _same_unit(first.load):
            raise InputError(str(rec.folder / "load.toml"), "",
                             f"a different load unit from {first.folder / 'load.toml'} "
                             "(pass --mixed-loads to fit them jointly)")
    return fitted, held_out


def _observations(recordings: list, retrack: bool) -> list:
    from calibration.replay import observe
    from calibration.track import track
    from calibration.trajectories import Trajectories

    observations = []
    for rec in recordings:
        for warning in profile_warnings(str(rec.folder / "profile.csv"),
                                        rec.profile.accel_mps2):
            sys.stderr.write(f"wrapbench calibrate: warning: {printable(warning, MESSAGE_CHARS)}\n")
        csv = rec.folder / "trajectories.csv"
        if csv.exists() and not retrack:
            tracked = Trajectories.from_csv(csv)
            rec.check_trajectories(tracked, str(csv))
            print(f"{shown_path(rec.folder)}: trajectories from {csv.name}"
                  f"{_replayed_after(rec.levels_before_g)}")
        else:
            result = track(rec)
            for warning in result.warnings:
                sys.stderr.write(f"wrapbench calibrate: warning: {shown_path(rec.folder)}: "
                                 f"{warning}\n")
            tracked = result.trajectories
            print(f"{shown_path(rec.folder)}: tracked {len(tracked.objects)} objects"
                  f"{_replayed_after(rec.levels_before_g)}")
        observations.append(observe(rec, tracked))
    return observations


def known_scales(entries: list[str]) -> tuple[tuple[str, float], ...]:
    """`--known NAME=SCALE ...` as (name, scale) pairs, each a wrap scale the fit could search
    (¼ to 4 ×), named once."""
    from calibration.fit import WRAP_PARAMS

    out: dict[str, float] = {}
    for entry in entries:
        name, equals, text = entry.partition("=")
        if name not in WRAP_PARAMS or name in out or not equals:
            raise InputError("arguments", "--known",
                             f"expected distinct NAME=SCALE with NAME one of "
                             f"{', '.join(WRAP_PARAMS)} (got {printable(entry)!r})")
        low, high = (2.0 ** v for v in WRAP_PARAMS[name])
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not low <= value <= high:
            raise InputError("arguments", "--known",
                             f"{name} must be a scale from {low:g} to {high:g} "
                             f"(got {printable(text)!r})")
        out[name] = value
    return tuple(out.items())


def _check_calibrate_args(args: argparse.Namespace) -> None:
    if args.budget is not None and args.budget < 10:
        raise InputError("arguments", "--budget", f"must be >= 10 (got {args.budget})")
    most = most_workers()
    if not 1 <= args.workers <= most:
        raise InputError("arguments", "--workers", f"must be from 1 to {most} (got "
                                                   f"{args.workers}): a simulation keeps a core "
                                                   "busy")
    if not (math.isfinite(args.max_residual_mm) and args.max_residual_mm > 0):
        raise InputError("arguments", "--max-residual-mm",
                         f"must be > 0 (got {args.max_residual_mm})")
    for flag, folders in (("DIR", args.recordings), ("--validate", args.validate)):
        _check_recording_folders(flag, folders)
    fitted = {d.resolve() for d in args.recordings}
    for d in args.validate:
        if d.resolve() in fitted:
            raise InputError("arguments", "--validate",
                             f"{d} is also fitted; validate on recordings the fit did not see")
    known_scales(args.known)


def _check_recording_folders(flag: str, folders: list[Path]) -> None:
    """Each a folder, and each once: a take given twice would count twice in the fit (or the
    validation) as if it were two."""
    seen: dict[Path, Path] = {}
    for d in folders:
        if not d.is_dir():
            raise InputError(str(d), flag, "not a folder (a recording folder holds video.mp4 "
                                           "or video.avi, profile.csv, setup.toml, load.toml)")
        if d.resolve() in seen:
            first = seen[d.resolve()]
            also = "" if first == d else f" (also as {first})"
            raise InputError("arguments", flag, f"{d} is given twice{also}: a take counts once")
        seen[d.resolve()] = d


def _outputs(out: Path) -> dict[str, Path]:
    """CAL.json and the two figures written beside it."""
    stem = out.with_suffix("")
    return {"json": out, "loss": Path(f"{stem}-loss.png"), "overlay": Path(f"{stem}-overlay.png")}


def _checkpoint(args: argparse.Namespace) -> Path:
    """Where the fit keeps its replays: --checkpoint, else beside --out."""
    if args.checkpoint is not None:
        return Path(args.checkpoint)
    return args.out.with_name(args.out.stem + ".checkpoint.jsonl")


def _check_outputs(args: argparse.Namespace, recordings: list) -> None:
    """Every output writable and none of them a file the run reads (checked once the
    recordings are read, before they are tracked); the checkpoint there to resume from."""
    from calibration.checkpoint import FORMAT_FAMILY
    inputs = [p for rec in recordings
              for p in (*rec.inputs(), rec.folder / "trajectories.csv")]
    outputs = _outputs(args.out)
    for path in outputs.values():
        check_output(path, "--out", inputs=inputs)
    checkpoint = _checkpoint(args)
    check_checkpoint(checkpoint, "--checkpoint", FORMAT_FAMILY, inputs=inputs)
    check_distinct({"--out": outputs["json"], "--out (loss figure)": outputs["loss"],
                    "--out (overlay figure)": outputs["overlay"], "--checkpoint": checkpoint})
    if args.resume and not checkpoint.exists():
        raise InputError(str(checkpoint), "--resume", "no checkpoint to resume from")


def run_calibrate(args: argparse.Namespace) -> int:
    from calibration.fit import FitSettings

    _check_calibrate_args(args)
    fitted, held = _recordings(args)
    _check_outputs(args, fitted + held)
    if args.params == "wrap" and all(rec.wrap is None for rec in fitted):
        raise InputError("arguments", "--params",
                         "wrap: none of the recordings is of a wrapped unit (no wrap.toml)")
    observations = _observations(fitted, args.retrack)
    held_out = _observations(held, args.retrack)
    settings = _budgeted(args.budget, observations, FitSettings(
        args.method, args.params, workers=args.workers, seed=args.seed,
        max_residual_m=args.max_residual_mm / 1000, known=known_scales(args.known)))
    checkpoint = _checkpoint(args)
    try:
        return _fitted_and_written(args, observations, held_out, settings, checkpoint)
    except KeyboardInterrupt as exc:
        if checkpoint.exists():
            exc.add_note(f"interrupted, nothing written; the fit's replays are kept in "
                         f"{shown_path(checkpoint)} (--resume continues it)")
        raise


def _budgeted(asked: int | None, observations: list, settings: FitSettings) -> FitSettings:
    """`settings` with the budget `--budget` asked, refused below what every stage needs to
    search at all; none asked, `fit.default_budget`, said when it is not the usual 300."""
    from calibration.fit import DEFAULT_BUDGET, default_budget, min_budget

    n = len(observations)
    if asked is None:
        budget = default_budget(observations, settings)
        if budget != DEFAULT_BUDGET:
            print(f"note: {n} recording{'s' * (n != 1)} share the fit's simulations: "
                  f"{budget}, not {DEFAULT_BUDGET}, so that each stage of the search has the "
                  "points it needs (--budget sets them)")
        return replace(settings, budget=budget)
    if asked < (least := min_budget(observations, settings)):
        raise InputError("arguments", "--budget",
                         f"must be >= {least} to fit these {n} recordings (got {asked})")
    return replace(settings, budget=asked)


def _fitted_and_written(args: argparse.Namespace, observations: list, held_out: list,
                        settings: FitSettings, checkpoint: Path) -> int:
    """Fit (the search's replays kept in `checkpoint`), validate and write; the checkpoint is
    removed once the fit has ended, written or refused (`_refused` may keep a named one)."""
    from calibration.checkpoint import ReplayLog
    from calibration.fit import fit
    from calibration.report import loss_figure, overlay_figure, png
    from calibration.validate import Unpredictable, validate
    from wrapenv.pool import ProcessPool

    t0 = time.perf_counter()
    with ReplayLog(checkpoint, observations, args.resume) as log, \
            tqdm(total=settings.budget, desc="simulations", unit="sim", leave=False,
                 disable=None) as bar:
        result = fit(observations, settings, lambda n: bar.update(n - bar.n), log)
    wall = time.perf_counter() - t0
    thin = _thin_search(observations, settings)
    if not result.converged:
        return _refused(result, settings, checkpoint, named=args.checkpoint is not None,
                        thin=thin)
    try:
        with ProcessPool(args.workers) as pool:
            checks = validate(held_out, result.calibration, pool)
    except Unpredictable as exc:
        checkpoint.unlink()
        sys.stderr.write(f"wrapbench calibrate: --validate: {printable(str(exc), MESSAGE_CHARS)}; "
                         "nothing written\n")
        return 1
    paths = _outputs(args.out)
    write_together({
        paths["json"]: result_json(_cal_json(result, settings, checks)),
        paths["loss"]: png(loss_figure(result.curve, f"{result.method}: "
                                       f"{result.simulations} simulations")),
        paths["overlay"]: png(overlay_figure(observations, result.fitted))})
    checkpoint.unlink()
    print(_summary(result) + thin)
    if settings.max_residual_m > DEFAULT_MAX_RESIDUAL_M:
        print(f"note: accepted under --max-residual-mm {1e3 * settings.max_residual_m:g}, "
              f"looser than the default {1e3 * DEFAULT_MAX_RESIDUAL_M:g} mm (CAL.json's "
              "acceptance; simulate and recommend warn of it)")
    for check in checks:
        print(_validation_summary(check))
    taken = f", {log.reused} replays from the checkpoint" if log.reused else ""
    print(f"{result.simulations} simulations ({_parts(result.simulations_by_part)}{taken}) in "
          f"{wall:.0f} s ({result.method}); wrote "
          f"{', '.join(shown_path(p) for p in paths.values())}")
    return 0


def _cal_json(result: FitResult, settings: FitSettings, checks: Sequence[Validation]
              ) -> dict[str, Any]:
    """CAL.json: the calibration as the bench reads it, then how it was found, how far to
    trust it and what it predicted of the takes it was not fitted on."""
    return result.calibration.to_dict() | {
        "residual_rms_m": result.residual_rms_m, "spread_rms_m": result.spread_rms_m,
        "replay_rms_m": result.replay_rms_m, "simulations": result.simulations,
        "simulations_by_part": result.simulations_by_part, "method": result.method,
        "advice": result.advice, "acceptance": _acceptance(result, settings),
        "validation": [c.to_dict() for c in checks]}


def _acceptance(result: FitResult, settings: FitSettings) -> dict:
    """The bound the fit was accepted under and the recording that came nearest it, so that a
    calibration accepted under a looser `--max-residual-mm` says so wherever it goes."""
    v = result.verdict
    return {"max_residual_m": settings.max_residual_m, "least_explained": v.source,
            "unexplained_rms_m": v.rms_m, "explained_by": v.by, "excused": list(v.excused),
            "near_threshold": list(result.near_threshold)}


def _parts(simulations_by_part: dict[str, int]) -> str:
    """'search 282, final replays 18, ...': where a fit's simulations went."""
    return ", ".join(f"{part.replace('_', ' ')} {n}" for part, n in simulations_by_part.items())


def _thin_search(observations: list, settings: FitSettings) -> str:
    """A note, when the budget asked is shared so thinly by the recordings that the friction
    search gets one local stage (`fit.friction_local_stages`), of the budget that gives it
    all; else ""."""
    from calibration.fit import friction_local_stages
    from calibration.surrogate import MAX_STAGES

    if (thin := friction_local_stages(observations, settings)) is None:
        return ""
    (local, budget), n = thin, len(observations)
    return (f"\nnote: with {n} recording{'s' * (n != 1)} the {settings.budget} simulations give "
            f"the friction search {local} local stage{'s' * (local != 1)} of "
            f"{MAX_STAGES - 1}: --budget {budget} or more gives it all {MAX_STAGES - 1}, as "
            "calibrate does when no --budget is asked (on five takes 480 fitted the true "
            "friction within ±0.03 kinetic and ±0.05 static on 5 seeds of 6, 300 on 2: "
            "docs/calibration.md, \"Five takes get the budget their search needs\")")


def _refused(result: FitResult, settings: FitSettings, checkpoint: Path, named: bool,
             thin: str = "") -> int:
    """Say what the refused fit found, with the advice (which test would pin what it missed),
    and why it is refused; exit status 1. The checkpoint goes, unless the engineer `named` it
    and a looser bound would accept the fit: then it keeps the replays to judge again.
    `thin`: the note of a budget spread thin (`_thin_search`), printed with the summary."""
    print("the refused fit (not written):\n" + _summary(result) + thin)
    acceptable = settings.max_residual_m < result.verdict.rms_m < math.inf
    kept = acceptable and named
    if not kept:
        checkpoint.unlink()
    written = "nothing written but the checkpoint" if kept else "nothing written"
    sys.stderr.write("wrapbench calibrate: the fit is refused: "
                     f"{printable(result.reason, MESSAGE_CHARS)}; {written}"
                     f"{_refusal_hint(checkpoint if kept else None) if acceptable else ''}\n")
    return 1


def _refusal_hint(kept: Path | None) -> str:
    """How a fit refused on a take a looser bound would accept can be accepted knowingly
    (`kept`: the checkpoint holding its replays, if the engineer named one)."""
    resume = (f"; {shown_path(kept)} keeps this fit's replays: with --resume it is judged "
              "again without simulating them" if kept is not None else "")
    return f" (a larger --max-residual-mm accepts it knowingly, and CAL.json says so{resume})"


def _summary(result: FitResult) -> str:
    cal = result.calibration
    lines = (["pair            static         kinetic        identified"] if cal.friction
             else ["friction: not fitted (the load file's values)"])
    for name, p in cal.friction.items():
        if p.identified:   # a pair the advice names is identified but not resolved
            lines.append(f"{name:14s}  {p.static:.3f} ± {p.static_std:.3f}  "
                         f"{p.kinetic:.3f} ± {p.kinetic_std:.3f}  yes"
                         + (", not resolved (advice)" if name in result.advice else ""))
        else:
            lines.append(f"{name:14s}  >= {p.static:.3f}      (never slipped)  no")
    scales = (("stiffness", "stiffness scale", cal.stiffness_scale, cal.stiffness_scale_std),
              ("tension", "tension scale", cal.tension_scale, cal.tension_scale_std),
              ("give", "load's give scale", cal.give_scale, cal.give_scale_std))
    if result.fitted_scales or cal.known:
        lines.append("wrap: " + ", ".join(
            f"{label} {value:.2f} (known)" if name in cal.known
            else f"{label} {value:.2f} ± {std:.2f}" if name in result.fitted_scales
            else f"{label} not fitted" for name, label, value, std in scales))
    else:
        lines.append("wrap: not fitted (the material card's and the load file's values)")
    lines += [f"advice: {name}: {text}" for name, text in result.advice.items()]
    spread = (f" (replays scatter {1e3 * result.spread_rms_m:.2f} mm about their mean)"
              if result.spread_rms_m else "")
    lines.append(f"residual RMS {1e3 * result.residual_rms_m:.2f} mm{spread}; one replay of "
                 f"the fitted values {1e3 * result.replay_rms_m:.2f} mm (what the acceptance "
                 "judges is what the replays' scatter leaves unexplained, next line)")
    v = result.verdict
    if v.source:
        excused = f", {' '.join(v.excused)} excused" if v.excused else ""
        lines.append(f"{'accepted' if result.converged else 'refused'}: the least explained "
                     f"recording, {shown_path(v.source)}, {1e3 * v.rms_m:.2f} mm unexplained by "
                     f"{v.by}{excused}")
    if result.refined_on:
        lines.append(f"refined: the search's estimate left {shown_path(result.refined_on)} "
                     "unexplained; the coefficients of the pairs its bodies rest on were moved "
                     "to where one of the search's replays made it, within the estimate's "
                     "uncertainty, and their standard deviations widened to the move")
    if result.converged:
        lines += [f"warning: {shown_path(source)} is a take near a threshold: the fitted values' "
                  "final replays left it unexplained until more were made; a fit can move the "
                  "coefficients that decide such an outcome to where it is the common one and "
                  "claim them resolved: validate this calibration on a level it was not fitted "
                  f"to (--validate){_apart(source, result)}" for source in result.near_threshold]
    elif v.source in result.near_threshold:
        lines.append(f"note: {shown_path(v.source)} may be a take near a threshold (a layer that "
                     "slides in some runs and holds in others), which more replays of the right "
                     f"values leave unexplained too{_apart(v.source, result)}")
    return "\n".join(lines)


def _apart(source: str, result: FitResult) -> str:
    """The advice on a take near a threshold, in a fit of several: its outcome pulls the
    coefficients its other bodies see (the 2-layer unit's 0.45 g take put bundle-bundle's
    kinetic coefficient +0.014 to +0.033 off on four fits of six, +0.003 to -0.019 without it),
    unless a pair slipped in it alone: without it that pair is only bounded, and what it
    decides is fitted to the bound (docs/calibration.md, "A take near a threshold pulls the
    other coefficients")."""
    if len(result.fitted) < 2:
        return ""
    text = ("; its rare outcome pulls the coefficients its other bodies see: fit the other "
            f"takes without it and validate on it (--validate {shown_path(source)})")
    if sole := result.sole_slips.get(source):
        pairs = " and ".join(sole)
        text += (f"; but {pairs} slipped in no other take: fitted without it, {pairs} would only "
                 f"be bounded and what depends on {pairs} fitted to a bound, so first add a "
                 f"level well past the onset of {pairs}")
    return text


def _validation_summary(check: Validation) -> str:
    from calibration.validate import REPRODUCED_SHARE

    lines = [f"validation {shown_path(check.source)} ({check.replays} replays): slide on its "
             "support at "
             "the end of the predictable frames, mm; 'uncertain': replayed with the calibrated "
             "values drawn within their standard deviations",
             "  object      recorded  predicted ± spread   error                uncertain ± spread"]
    rows = [*check.objects.items(), *((f"layer {k}", c) for k, c in check.layers.items())]
    lines += [_validation_row(name, c) for name, c in rows]
    if any(layer > 1 for layer in check.layers_on_pallet):   # the first layer's is its slip
        lines.append("  on the pallet (each bundle's slip plus its supports', as EUMOS measures):")
        lines += [_validation_row(f"layer {k}", c) for k, c in check.layers_on_pallet.items()]
    layer, c = check.verdict
    moved = (f"layer {layer}, moved {1e3 * c.recorded_m:.1f} mm on the pallet" if layer else
             f"the pallet, slid {1e3 * c.recorded_m:.1f} mm on the sled")
    lines.append(f"  {moved}: {c.uncertain_spreads:.1f} spreads from the prediction over the "
                 "calibration's uncertainty, "
                 + ("within that spread" if c.explained else "outside that spread: the "
                    "recording shows something the calibrated bench does not do"))
    if c.reproduced is not None:
        lines.append(f"  {c.reproduced:.0%} of the replays with the calibrated values come within "
                     f"{REPRODUCED_SHARE:.0%} of it (a unit near a threshold has several outcomes"
                     ", and a take is one of them)")
    return "\n".join(lines)


def _signed_pct(value: float) -> str:
    """A signed whole percentage, without the "-0" of a small negative error."""
    text = f"{value:+.0f}"
    return "0" if text in ("+0", "-0") else text


def _validation_row(name: str, c: Check) -> str:
    return (f"  {name:10s}  {1e3 * c.recorded_m:8.1f}  {1e3 * c.predicted_m:8.1f} ± "
            f"{1e3 * c.spread_m:5.1f}  {1e3 * c.error_m:+7.1f}{_error_words(c):17s}  "
            f"{1e3 * c.uncertain_m:8.1f} ± {1e3 * c.uncertain_spread_m:5.1f}")


def _error_words(c: Check) -> str:
    """The error as a share of the recorded slide, and which way: a slide backwards (-x) is
    negative, so a signed share alone reads an over-prediction as an under-prediction."""
    if c.error_pct is None:
        return ""
    if c.predicted_m * c.recorded_m > 0 and abs(c.error_pct) >= 0.5:
        longer = abs(c.predicted_m) > abs(c.recorded_m)
        return f" ({abs(c.error_pct):.0f} % {'longer' if longer else 'shorter'})"
    return f" ({_signed_pct(c.error_pct)} %)"

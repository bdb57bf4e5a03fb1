"""`wrapbench synth` and `wrapbench track`: the recording side of the command line.

`recommender.cli` owns the `wrapbench` parser and registers these subcommands; their options and
output live here, beside the code they drive. Errors of input are `InputError`s, which the CLI
turns into one line and exit status 2.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from tqdm import tqdm

from wrapenv.config import InputError
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat


def add_synth(sub: argparse._SubParsersAction, level_type) -> None:
    p = sub.add_parser("synth", help="make a synthetic bench recording with ground truth")
    p.add_argument("load", type=Path, help="LOAD.toml")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="recording folder to create (must not exist or be empty)")
    p.add_argument("--wrap", type=Path, metavar="WRAP.toml", help="wrap the unit in this format")
    p.add_argument("--level", type=level_type, default=0.4, metavar="G",
                   help="test level in g (default 0.4)")
    p.add_argument("--seed", type=int, default=0, help="textures, noise and friction jitter")
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


def run_synth(args: argparse.Namespace) -> int:
    from calibration.synth import synthesize

    load = LoadUnit.from_toml(args.load)
    wrap = WrapFormat.from_toml(args.wrap) if args.wrap else None
    for flag, value in (("--stiffness-scale", args.stiffness_scale),
                        ("--tension-scale", args.tension_scale)):
        if not (math.isfinite(value) and value > 0):
            raise InputError("arguments", flag, f"must be > 0 (got {value})")
    t0 = time.perf_counter()
    try:
        rec = synthesize(load, args.out, wrap=wrap, level_g=args.level, seed=args.seed,
                         size=args.size, fps=args.fps, friction_jitter=args.friction_jitter,
                         stiffness_scale=args.stiffness_scale, tension_scale=args.tension_scale)
    except ValueError as exc:  # an unphysical simulation: nothing to record
        if isinstance(exc, InputError):
            raise
        sys.stderr.write(f"wrapbench synth: {exc}; no recording written\n")
        return 1
    frames = round(rec.profile.t_s[-1] * rec.fps) + 1
    print(f"wrote {rec.folder}: {rec.video.name} {args.size[0]}x{args.size[1]}, "
          f"{frames} frames at {rec.fps:g} fps, {rec.px_per_m:g} px/m, level {args.level:.2f} g"
          f"{', wrapped' if wrap else ''}, in {time.perf_counter() - t0:.0f} s")
    return 0


def run_track(args: argparse.Namespace) -> int:
    from calibration.recording import Recording, Truth
    from calibration.track import track
    from calibration.trajectories import error_vs_truth

    rec = Recording.read(args.recording)
    out = args.out if args.out is not None else rec.folder / "trajectories.csv"
    for path, flag in ((out, "--out"), (args.debug_video, "--debug-video")):
        if path is not None and not path.resolve().parent.is_dir():
            raise InputError(str(path), flag, "the folder to write into does not exist")
    t0 = time.perf_counter()
    with tqdm(desc="frames", unit="frame", leave=False, disable=None) as bar:
        def progress(frame: int, frames: int) -> None:
            bar.total = frames
            bar.update(frame + 1 - bar.n)

        result = track(rec, tracker=args.tracker, debug_video=args.debug_video,
                       progress=progress)
    wall = time.perf_counter() - t0
    result.trajectories.to_csv(out)
    for warning in result.warnings:
        sys.stderr.write(f"wrapbench track: warning: {warning}\n")
    objects = result.trajectories.objects
    frames = max((len(p.t_s) for p in objects.values()), default=0)
    print(f"wrote {out}: {len(objects)} objects ({', '.join(objects)}), {frames} frames in "
          f"{wall:.1f} s ({frames / wall:.0f} frames/s, tracker {args.tracker})")
    if (rec.folder / "truth.json").exists():
        errors = error_vs_truth(result.trajectories, Truth.read(rec.folder).objects)
        print("error against truth.json (displacement):  object  RMS mm  max mm")
        for name, e in errors.items():
            print(f"{name:>44s}  {1e3 * e.rms_m:6.2f}  {1e3 * e.max_m:6.2f}")
    return 0

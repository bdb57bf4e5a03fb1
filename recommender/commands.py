"""What the bench's commands `recommend`, `simulate` and `train` (recommender/recommend.py,
recommender/simulate.py and recommender/train.py) share.

Each command takes the parsed arguments, checks every input and output before any simulation,
and maps the domain's errors (which name domain fields) onto the flags a user typed.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, shown_path
from wrapenv.eumos import EUMOS_LIMITS, Limits
from wrapenv.load import Layout
from wrapenv.material import check_hours_since_wrapping
from wrapenv.profile import PulseProfile
from wrapenv.wrap import Web, WrapFormat

#: Flags of the domain's fields, for messages that name what the user typed.
FLAGS = {"target_g": "--target", "start_g": "--start", "level_g": "--level",
         "material": "--material", "hours_since_wrapping": "--hours-since-wrapping",
         "timesteps": "--timesteps", "workers": "--envs", "max_minutes": "--minutes",
         "material_weight": "--material-weight", "log_std_init": "--log-std-init",
         "tests_per_episode": "--tests-per-episode"}


def as_flag(exc: InputError) -> InputError:
    """A domain error about an argument, naming the flag instead of the field."""
    return InputError("arguments", FLAGS.get(exc.field, exc.field), exc.message)


def check_target(target_g: float, flag: str = "--target") -> None:
    """A target level the bench can produce, or a usage error naming the flag."""
    try:
        PulseProfile(target_g)
    except InputError as exc:
        raise InputError("arguments", flag, exc.message) from None


def named_web(key: str) -> Web:
    """A named card on the default web, or a usage error naming --material."""
    try:
        return Web.named(key)
    except InputError as exc:
        raise as_flag(exc) from None


def warn(command: str, messages: tuple[str, ...], said: list[str] | None = None) -> None:
    """Each message on stderr, and into `said` for the report (which repeats what was said)."""
    for message in messages:
        sys.stderr.write(f"wrapbench {command}: warning: {message}\n")
    if said is not None:
        said.extend(messages)


def say_written(*paths: Path | None) -> None:
    """What a command wrote (None: an output not asked for), one line, as `synth`, `track` and
    `calibrate` say it (nothing: no line): a user who asked for a report and a JSON sees where
    they went."""
    written = [shown_path(path) for path in paths if path is not None]
    if written:
        print(f"wrote {', '.join(written)}")


def read_calibration(path: Path, command: str, said: list[str] | None = None) -> Calibration:
    """CAL.json, with what its user should know said once (a fit accepted knowingly)."""
    calibration = Calibration.from_json(path)
    warn(command, calibration.warnings(), said)
    return calibration


def wrap_json(simulated: WrapFormat, laid: WrapFormat, layout: Layout,
              hours_since_wrapping: float) -> dict[str, Any]:
    """The JSON keys of a wrap: what was simulated (`format`: bands as simulated, their
    tensions relaxed for the hours since wrapping and calibrated; the program as entered),
    the web laid and the cycle time."""
    cycle = laid.cycle_time_s
    relaxed = {"hours_since_wrapping": hours_since_wrapping,
               "tension_retained": round(laid.material.relaxation.retained(
                   hours_since_wrapping), 4)}
    return {"format": {**simulated.to_json(), **relaxed,
                       **({"program": laid.to_json()["program"]}
                          if laid.program is not None else {})},
            "material_used": asdict(laid.material_used_on(layout)),
            "cycle_time_s": round(cycle, 3), "pallets_per_hour": round(laid.pallets_per_hour, 2)}


#: The least limit on the shift between layers the flag takes: 0.1 % of a 0.8 m unit is 0.8 mm,
#: about what the bench reproduces of itself; below it a figure is a fraction typed for a
#: percentage (the domain's `Limits` takes any fraction in (0, 1]).
MIN_LAYER_SHIFT_PCT = 0.1


def criteria_limits(args: argparse.Namespace) -> Limits:
    """The criteria asked for: EUMOS 40509's, and the shift between layers if given."""
    pct = args.layer_shift_limit_pct
    if pct is None:
        return EUMOS_LIMITS
    if not MIN_LAYER_SHIFT_PCT <= pct <= 100:
        fraction = (": a fraction? The flag is in percent (vendors quote 2)"
                    if 0 < pct < MIN_LAYER_SHIFT_PCT else "")
        raise InputError("arguments", "--layer-shift-limit-pct",
                         f"must be in [{MIN_LAYER_SHIFT_PCT:g}, 100] % of the load height (got "
                         f"{pct:g}){fraction}")
    return Limits(layer_shift_fraction=pct / 100)


def check_hours(hours: float) -> None:
    """`--hours-since-wrapping`, checked before any simulation (with or without a wrap)."""
    try:
        check_hours_since_wrapping(hours)
    except InputError as exc:
        raise as_flag(exc) from None

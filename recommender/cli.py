"""`wrapbench`: the command line of the virtual bench.

Exit status (CONTRACTS.md): 0 success; 1 the run completed without the answer asked for (the
load failed the asked test, no passing program was found, a simulation became unphysical, a
fit was refused or its validation not predicted); 2 bad input or usage, with one line on stderr
naming the file and the field; 130 or 143 interrupted (SIGINT, SIGTERM), nothing written.
"""

from __future__ import annotations

import argparse
import logging  # noqa: F401  its fork hooks first: `_Forking` brackets them
import math
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from calibration import commands
from calibration.commands import level_g, seed
from recommender import recommend, simulate
from recommender.parallel import BACKENDS
from wrapenv import __version__
from wrapenv.config import InputError
from wrapenv.load import EXAMPLE_LOAD, ORIENTATIONS
from wrapenv.pool import stop
from wrapenv.uncertainty import TRANSPORT_HOURS


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line and exits with status 2, and takes a
    flag only as written (`--lev` is no `--level`: a script must not change meaning when a
    flag is added)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **{**kwargs, "allow_abbrev": False})

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"{self.prog}: error: {message}{self._greedy_hint(message)}\n")
        sys.exit(2)

    def parse_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                   namespace: argparse.Namespace | None = None) -> argparse.Namespace:
        """As argparse's, but words no option took are reported by the command they were
        given to (`wrapbench simulate: ...`), with a hint when a value follows a flag that
        takes one value a time (`--level 0.2 0.3`)."""
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:
            command = self._command(parsed)
            command.error(f"unrecognized arguments: {' '.join(extras)}"
                          f"{command._repeat_hint(extras)}")
        return parsed

    def _command(self, parsed: argparse.Namespace) -> _Parser:
        """The subcommand's parser `parsed` went through (this one if none)."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                chosen = action.choices.get(getattr(parsed, action.dest, None) or "")
                if isinstance(chosen, _Parser):
                    return chosen
        return self

    def _repeat_hint(self, extras: list[str]) -> str:
        """A number no option took most likely followed a flag that takes one value."""
        repeatable = [a.option_strings[0] for a in self._actions
                      if isinstance(a, argparse._AppendAction) and a.option_strings]
        if not (repeatable and _is_number(extras[0])):
            return ""
        takes = "takes one value" if len(repeatable) == 1 else "take one value each"
        return f" ({' and '.join(repeatable)} {takes}: give the flag once for each value)"

    def _greedy_hint(self, message: str) -> str:
        """A missing positional after an option that takes several values was most likely
        taken by it (`calibrate --known tension=1 take1/`)."""
        greedy = [a.option_strings[0] for a in self._actions
                  if a.option_strings and a.nargs in ("+", "*")]
        if not (greedy and message.startswith("the following arguments are required")):
            return ""
        return (f" ({', '.join(greedy)} take every word after them: put the "
                f"{'folders' if 'DIR' in message else 'arguments'} before them)")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _number(text: str) -> float:
    """argparse's type for a finite number (hours, seconds, weights); its errors say so."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a number (got {text!r})")
    return value


def _layer_shift_flag(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--layer-shift-limit-pct", type=_number, metavar="P",
                        help="also fail a level whose layers shifted on each other by more "
                             "than P %% of the load height (vendors quote 2)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="wrapbench", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    _add_simulate(sub)
    rec = sub.add_parser("recommend", help="search the wrapping program with the least web that "
                                           "passes EUMOS 40509 up to the target")
    _add_recommend_problem(rec)
    _add_recommend_run(rec)
    _add_train(sub)
    commands.add_synth(sub)
    commands.add_track(sub)
    commands.add_calibrate(sub)
    return parser


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    sim = sub.add_parser("simulate", help="run a load unit on the virtual ESTL bench")
    sim.add_argument("load", type=Path, help="LOAD.toml")
    sim.add_argument("--wrap", type=Path, metavar="WRAP.toml",
                     help="wrap the unit by this program or these bands (default: unwrapped)")
    sim.add_argument("--calibration", type=Path,
                     help="CAL.json with fitted friction (and wrap stiffness and tension scales)")
    sim.add_argument("--level", type=level_g, action="append", metavar="G",
                     help="test level in g (repeatable)")
    sim.add_argument("--eumos", action="store_true",
                     help="EUMOS sequence from --start up to --target, stopping at the first "
                          "failure (the default when no level or profile is given)")
    sim.add_argument("--target", type=level_g, metavar="G",
                     help="last level of the EUMOS sequence (default 0.5 g)")
    sim.add_argument("--start", type=level_g, metavar="G",
                     help="first level (default 0.2 g, or the target when it is lower)")
    sim.add_argument("--profile", type=Path, help="drive the sled by a measured profile.csv")
    sim.add_argument("--orientation", choices=ORIENTATIONS,
                     help="pallet side along the motion (default: as the load file lays it out)")
    sim.add_argument("--hours-since-wrapping", type=_number, default=0.0, metavar="H",
                     help="test the wrap after its tension relaxed for H hours (default 0)")
    sim.add_argument("--fresh", action="store_true",
                     help="restack and rewrap the unit before every level (default: one unit "
                          "through the levels, each starting where the last left it, as a lab)")
    _layer_shift_flag(sim)
    sim.add_argument("--samples", type=int, metavar="K",
                     help="also run the levels in K samples of what the bench does not know "
                          "(recommend's: friction, mass, web stiffness, tension, relaxation, "
                          "the load's give; a calibration's spreads where it gives them): the "
                          "pass probability and the worst sample (the exit status stays the "
                          "nominal run's)")
    sim.add_argument("--seed", type=seed, metavar="N",
                     help="with --samples: which samples (default 0, recommend's)")
    sim.add_argument("--workers", type=int, metavar="N",
                     help="with --samples: parallel simulations (default: all cores)")
    sim.add_argument("--json", type=Path, metavar="OUT", help="write the verdict as JSON")
    sim.add_argument("--plot", type=Path, metavar="OUT.png", help="plot displacement vs time")
    sim.add_argument("--report", type=Path, metavar="DIR",
                     help="write report.html (the one-page test report), its figures and "
                          "test.mp4/test.webm (the highest level run) into DIR")
    sim.add_argument("--tension-map", type=Path, metavar="OUT.png",
                     help="with --wrap: the envelope unrolled, coloured by each place's peak "
                          "utilisation, torn and opened places marked")


def _add_recommend_problem(rec: argparse.ArgumentParser) -> None:
    """The load, the web, the method and where it runs, the targets and what is uncertain."""
    rec.add_argument("load", type=Path, nargs="?", default=EXAMPLE_LOAD,
                     help="LOAD.toml (default: the bundled 2-layer example)")
    rec.add_argument("--calibration", type=Path, help="CAL.json (friction and its uncertainty)")
    rec.add_argument("--material", default=None,
                     help="kraft (default) or lldpe, on a 0.5 m web and the default machine")
    rec.add_argument("--web", type=Path, metavar="WRAP.toml",
                     help="the web and machine of this WRAP.toml instead: its material (a named "
                          "card or a [material] table), web_width_m and [machine]; its program "
                          "or bands are checked but not used")
    rec.add_argument("--target", type=level_g, default=0.5, metavar="G", help="default 0.5 g")
    rec.add_argument("--method", choices=("cmaes", "ppo"), default="cmaes",
                     help="cmaes: robust search (default); ppo: a trained policy's proposal, "
                          "verified in simulation, and searched from if it does not hold "
                          "(needs --policy)")
    rec.add_argument("--policy", type=Path, metavar="FILE",
                     help="policy.zip written by `wrapbench train` (with --method ppo)")
    rec.add_argument("--samples", type=int, default=3, metavar="K",
                     help="robust samples of the uncertain parameters per candidate "
                          "(default 3)")
    rec.add_argument("--margin", type=float,
                     help="wanted EUMOS margin of the worst sample (default 0.2)")
    rec.add_argument("--budget", type=int, metavar="N",
                     help="most candidate programs to try (default 48)")
    rec.add_argument("--rounds", type=int, metavar="R",
                     help="search rounds at most (default 2): when every pass of a round fails "
                          "its verification, or it found none, the next searches again with one "
                          "more sample, twice the budget and every tension at the top (after no "
                          "pass, from the strongest program, only if that holds); with --method "
                          "ppo round 1 is the policy's proposal (default 3; --rounds 1: it "
                          "alone)")
    rec.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                     help="parallel simulations (default: all cores)")
    rec.add_argument("--backend", choices=BACKENDS, default="process",
                     help="where simulations run: worker processes here (default) or Ray "
                          "(needs `pip install .[ray]`)")
    rec.add_argument("--ray-address", metavar="ADDRESS",
                     help="with --backend ray: join this cluster ('auto', 'ray://host:10001'); "
                          "default: start a local Ray instance of --workers CPUs")
    rec.add_argument("--seed", type=seed, default=0,
                     help="seed of the search and of the samples (same seed, same answer)")
    rec.add_argument("--orientation", choices=(*ORIENTATIONS, "both"), default="both",
                     help="pallet side(s) along the motion a program must pass (default both: "
                          "a load is only as safe as its weaker orientation)")
    rec.add_argument("--target-long", type=level_g, metavar="G",
                     help="target with the long side along the motion (default --target)")
    rec.add_argument("--target-short", type=level_g, metavar="G",
                     help="target with the short side along the motion (default --target)")
    rec.add_argument("--hours-since-wrapping", type=_number, default=TRANSPORT_HOURS, metavar="H",
                     help=f"hours the wrap relaxes before the road (default {TRANSPORT_HOURS:g}: "
                          "ASTM D5414 rests a wrapped load 16 h before testing)")
    rec.add_argument("--fresh", action="store_true",
                     help="verify on a fresh unit per level (default: one unit through the "
                          "EUMOS sequence, as a lab)")
    rec.add_argument("--ordered-tensions", action=argparse.BooleanOptionalAction, default=True,
                     help="lay the bottom and top wraps at least as tight as the spiral, as "
                          "machine practice orders the zones (default; --no-ordered-tensions "
                          "searches each zone's tension freely)")
    _layer_shift_flag(rec)


def _add_recommend_run(rec: argparse.ArgumentParser) -> None:
    """The price of cycle time, the checkpoint and the outputs."""
    rec.add_argument("--max-cycle-s", type=_number, default=math.inf, metavar="S",
                     help="only programs the machine runs within S seconds per pallet")
    rec.add_argument("--cycle-weight", type=_number, metavar="W",
                     help="price of cycle time: W machine-default programs' web per second "
                          "(default 0: web only)")
    rec.add_argument("--checkpoint", type=Path, metavar="FILE",
                     help="search state (JSON) written after every generation and removed when "
                          "the search ends (default: beside --json, else none)")
    rec.add_argument("--resume", action="store_true", help="continue from the checkpoint")
    rec.add_argument("--json", type=Path, metavar="OUT", help="write the result as JSON")
    rec.add_argument("--wrap-out", type=Path, metavar="WRAP.toml",
                     help="write the recommended program as a WRAP.toml")
    rec.add_argument("--report", type=Path, metavar="DIR",
                     help="write report.html (the one-page report), displacement.png, "
                          "tension_map.png, search.png and test.mp4/test.webm (the "
                          "recommended program's test at the target level) into DIR")


def _add_train(sub: argparse._SubParsersAction) -> None:
    tr = sub.add_parser("train", help="train a PPO policy on random load units "
                                      "(wrapenv/WrapBenchRandom-v3)")
    tr.add_argument("--out", type=Path, required=True, metavar="DIR",
                    help="folder for policy.zip, checkpoints/ and log.csv")
    tr.add_argument("--timesteps", type=int, default=2048,
                    help="units tested, one program each (rounded up to whole rollouts; "
                         "default 2048)")
    tr.add_argument("--envs", type=int, default=os.cpu_count() or 1,
                    help="processes simulating the episodes (default: all cores)")
    tr.add_argument("--material", default="kraft",
                    help="the web the policy programs: kraft (default) or lldpe")
    tr.add_argument("--target", type=level_g, default=0.5, metavar="G",
                    help="the level its programs must pass (default 0.5 g)")
    tr.add_argument("--seed", type=seed, default=0, help="seed of the random units and of PPO")
    tr.add_argument("--calibration", type=Path,
                    help="CAL.json: random units spread about its friction, and the policy "
                         "observes its uncertainty (for `recommend --method ppo --calibration`)")
    tr.add_argument("--test", choices=("verified", "nominal"), default="verified",
                    help="what each episode's program is judged by: verified (default: the test "
                         "`recommend --method ppo` verifies on, one episode at a time: a side "
                         "drawn at random, one sample of what the bench does not know, the wrap "
                         "relaxed 16 h) or nominal (the unit's long side as given, freshly "
                         "wrapped, as policies trained before 2026-11-28 were)")
    tr.add_argument("--material-weight", type=_number, default=0.6, metavar="W",
                    help="the reward's price on web, in machine-default programs' web (default "
                         "0.6; 1 before 2026-12-01); lower asks the policy for programs that "
                         "hold in more samples")
    tr.add_argument("--log-std-init", type=_number, default=0.0, metavar="L",
                    help="log of the exploration noise's initial standard deviation, in "
                         "actions scaled to [-1, 1] (SB3's log_std_init; default 0); -1 lets a "
                         "film policy's proposals differ by unit (docs/recommend.md)")
    tr.add_argument("--tests-per-episode", type=int, default=1, metavar="K",
                    help="tests of each episode's program, each its own side and sample, "
                         "judged by the worst as the verification judges (default 1; K x the "
                         "simulations per episode)")
    tr.add_argument("--minutes", type=float, default=None, metavar="M",
                    help="stop after M minutes of training and write the policy learned so far "
                         "(default: run all --timesteps)")
    tr.add_argument("--resume", action="store_true",
                    help="continue the run in --out from its last checkpoint, up to "
                         "--timesteps in all: an interrupted run, or a finished one trained on "
                         "(give the flags it was started with)")


class _Terminated(KeyboardInterrupt):
    """SIGTERM, unwound like Ctrl-C so that what a command half wrote is removed on the way
    out (the default action would end the process and leave its worker processes behind)."""


class _Forking:
    """Forks and the command's signals: whether the process is inside `os.fork` (a worker pool
    starting), and which process the handlers are the command's in. A signal that comes during
    a fork is handled in the first Python code after it, the fork hooks (logging's lock
    release), where an exception cannot be raised: Python prints it, 'Exception ignored in
    <function _releaseLock>' with a traceback, and drops it. Registered after logging's hooks,
    these bracket them."""

    now = False
    #: The process whose handlers these are (`main` sets it). A process forked from it has them
    #: too until its pool's initializer gives it a worker's (`wrapenv.pool`).
    owner_pid = os.getpid()

    @classmethod
    def starts(cls) -> None:
        cls.now = True

    @classmethod
    def ended(cls) -> None:
        cls.now = False


os.register_at_fork(before=_Forking.starts, after_in_parent=_Forking.ended,
                    after_in_child=_Forking.ended)


def _in_a_new_worker(signum: int) -> bool:
    """A worker not yet started takes a worker's action: it dies of SIGTERM and leaves Ctrl-C
    to its parent. With the command's handler, its pool's SIGTERM raised `_Terminated` in its
    start-up and printed a traceback on the command's stderr (the interrupt tests, once in 15
    runs, 2026-11-27: a verification's pool was starting)."""
    if os.getpid() == _Forking.owner_pid:
        return False
    if signum == signal.SIGTERM:
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
    return True


def _deferred(signum: int) -> bool:
    """Inside a fork: the signal is sent again a moment later, to be raised where it can be."""
    if not _Forking.now:
        return False
    threading.Timer(0.01, os.kill, (os.getpid(), signum)).start()
    return True


def _terminate(signum: int, frame: object) -> None:
    if _in_a_new_worker(signum) or _deferred(signum):
        return
    _ignore_interrupts()
    raise _Terminated


def _interrupt(signum: int, frame: object) -> None:
    """Ctrl-C, raised once: a second one while the command winds down is ignored, not raised
    inside whatever runs then."""
    if _in_a_new_worker(signum) or _deferred(signum):
        return
    _ignore_interrupts()
    raise KeyboardInterrupt


def _ignore_interrupts() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _stop_children() -> None:
    """Any worker process an interrupted command still has, stopped (`wrapenv.pool.stop`). Its
    pools stop theirs, but once in the test suite (2026-11-27) an idle worker outlived an
    interrupted search, and Python joins every child process at exit: the command waited for
    it forever. The command's process owns its children; none has work left to finish."""
    stop(multiprocessing.active_children())


def _run_train(args: argparse.Namespace) -> int:
    """`train`, whose module brings torch and stable-baselines3: imported for a training run
    only, so that the other commands start without them."""
    from recommender import train

    return train.run_train(args)


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    command = {"simulate": simulate.run_simulate,
               "recommend": recommend.run_recommend,
               "train": _run_train,
               "synth": commands.run_synth, "track": commands.run_track,
               "calibrate": commands.run_calibrate}[args.command]
    _Forking.owner_pid = os.getpid()
    handlers = {signal.SIGTERM: signal.signal(signal.SIGTERM, _terminate),
                signal.SIGINT: signal.getsignal(signal.SIGINT)}
    if handlers[signal.SIGINT] is signal.default_int_handler:   # not when ignored (`cmd &`)
        signal.signal(signal.SIGINT, _interrupt)
    try:
        return command(args)
    except InputError as exc:
        sys.stderr.write(f"wrapbench {args.command}: {exc}\n")
        return 2
    except KeyboardInterrupt as exc:
        _ignore_interrupts()  # a second Ctrl-C: no traceback
        _stop_children()
        notes = getattr(exc, "__notes__", None) or ["interrupted, nothing written"]
        sys.stderr.write(f"wrapbench {args.command}: {notes[-1]}\n")
        return 128 + (signal.SIGTERM if isinstance(exc, _Terminated) else signal.SIGINT)
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)


def run() -> int:
    """The `wrapbench` command: `main`, then, if it was interrupted, a Ctrl-C that comes while
    the process winds down (the interpreter joins the worker pool's threads at exit) ignored
    too. `main` itself restores its caller's handlers, as an in-process caller needs; a second
    Ctrl-C that lands just as it has, or one while it reads its arguments (before it sets its
    own), ends the command quietly with Ctrl-C's status: the first already said what it left."""
    try:
        code = main()
        if code in (128 + signal.SIGINT, 128 + signal.SIGTERM):
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        return 128 + signal.SIGINT
    except BrokenPipeError:
        # stdout's reader went away (`wrapbench simulate ... | head`): end as a Unix tool does
        # on SIGPIPE, without a traceback; stdout goes to devnull so the exit's flush cannot
        # raise again (Python's documented way, library/signal.html)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    return code


if __name__ == "__main__":
    sys.exit(run())

"""A robust search's checkpoint: data (JSON), never a pickle.

The file holds what identifies the search (the load, the settings that change what is asked or
how it is scored) and every generation as it was told to CMA-ES: the candidates asked ("x"),
their objective, margins and verdicts per sample, and the fidelity each was judged with
("screening", "default", or "dominated": not simulated, see `recommender.search`). A resumed
search replays the generations into a new CMA-ES with the same seed, without simulating, and
refuses a file of another search. A search in a later round (`SearchSettings.in_round`) also
records its round, what the rounds before it spent and the program it started from ("round";
absent: the first round).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from wrapenv.config import InputError, is_finite_number, read_json, write_atomic
from wrapenv.design import N_PARAMS

#: Every version of the format starts so: what an existing file must be to be overwritten.
FORMAT_FAMILY = "wrapbench-search/"
#: /2: every candidate records the fidelity it was judged with (multi-fidelity search).
CHECKPOINT_FORMAT = FORMAT_FAMILY + "2"
#: The keys of one checkpointed generation that are lists with one entry per candidate ("x": the
#: asked vectors); "simulations" counts the levels the generation simulated.
GENERATION_KEYS = ("x", "objective", "margins", "passed", "fidelity")


@dataclass(frozen=True)
class Round:
    """The search round under way, and the candidates and levels simulated by the rounds
    before it (they found no pass, or their passes all failed their verification: nothing of
    them is replayed)."""

    number: int = 1
    earlier_candidates: int = 0
    earlier_simulations: int = 0
    #: The search vector the round starts from, chosen by the rounds before it (None: the
    #: first round's, `recommender.search.LIGHT_START`).
    start: tuple[float, ...] | None = None

    def next(self, candidates: int, simulations: int, start: tuple[float, ...]) -> Round:
        """The round after this one, which spent `candidates` and `simulations`, starting from
        `start`."""
        return Round(self.number + 1, self.earlier_candidates + candidates,
                     self.earlier_simulations + simulations, tuple(start))


#: The round every search starts in.
FIRST_ROUND = Round()


def save(path: Path | None, identity: dict[str, Any], generations: list[dict[str, Any]],
         round_: Round = FIRST_ROUND) -> None:
    """Write the checkpoint atomically (nothing half-written if interrupted); None: nowhere."""
    if path is None:
        return
    data = {"format": CHECKPOINT_FORMAT, "problem": identity, "generations": generations,
            **({} if round_ == FIRST_ROUND else {"round": asdict(round_)})}
    write_atomic(path, (json.dumps(data) + "\n").encode())


def read_round(path: Path | None) -> Round:
    """The round the checkpoint at `path` was written in (its format is checked by `load`)."""
    given = _read(path).get("round", {})
    counts = ("number", "earlier_candidates", "earlier_simulations")
    if not (isinstance(given, dict) and set(given) <= set(asdict(FIRST_ROUND))
            and all(type(given[k]) is int for k in counts if k in given)):  # a bool is no count
        raise InputError(str(path), "round", f"must be an object of whole numbers "
                                             f"({', '.join(counts)}) and a start")
    start = given.get("start")
    if start is not None and not (isinstance(start, list) and len(start) == N_PARAMS
                                  and all(map(is_finite_number, start))):
        raise InputError(str(path), "round.start", f"must be a list of {N_PARAMS} finite "
                                                   f"numbers (a search vector)")
    round_ = Round(**{**given, "start": None if start is None else tuple(map(float, start))})
    if round_.number < 1 or round_.earlier_candidates < 0 or round_.earlier_simulations < 0:
        raise InputError(str(path), "round", "holds a number the search never writes (a round "
                                             "is >= 1, what earlier rounds spent >= 0)")
    if (round_.start is None) != (round_.number == 1):
        raise InputError(str(path), "round.start", "a later round has a start, the first none")
    return round_


def load(path: Path | None, identity: dict[str, Any]) -> list[dict[str, Any]]:
    """The generations of the checkpoint at `path`, if it is this search's (`identity`)."""
    data = _read(path)
    problem = data.get("problem")
    if not isinstance(problem, dict):
        raise InputError(str(path), "problem", "must be an object")
    for key in sorted(identity.keys() | problem.keys()):  # a setting on one side only differs
        if problem.get(key) != identity.get(key):
            raise InputError(str(path), f"problem.{key}", "the checkpoint is of another "
                             "search (load, material, target, seed, calibration or fidelity "
                             "differ)")
    generations = data.get("generations")
    if not isinstance(generations, list) or not all(
            isinstance(g, dict) and all(isinstance(g.get(k), list) for k in GENERATION_KEYS)
            for g in generations):
        raise InputError(str(path), "generations", f"must be a list of objects with the lists "
                                                   f"{', '.join(GENERATION_KEYS)}")
    for k, g in enumerate(generations):
        _check_values(g, f"generations[{k}]", str(path))
    return generations


def _read(path: Path | None) -> dict[str, Any]:
    """The checkpoint file's data, if it is one of this version."""
    if path is None or not path.exists():
        raise InputError(str(path), "resume", "no checkpoint to resume from")
    data = read_json(path)
    if data.get("format") != CHECKPOINT_FORMAT:
        raise InputError(str(path), "format", f"not a wrapbench search checkpoint of this "
                                              f"version ({CHECKPOINT_FORMAT})")
    return data


def _check_values(generation: dict[str, Any], where: str, source: str) -> None:
    """What the search tells CMA-ES must be what it wrote: finite numbers and real booleans (a
    NaN margin would rank first, and "false" is a true string)."""
    checks = {"x": lambda row: isinstance(row, list) and all(map(is_finite_number, row)),
              "objective": is_finite_number,
              "margins": lambda row: isinstance(row, list) and all(map(is_finite_number, row)),
              "passed": lambda row: isinstance(row, list)
              and all(isinstance(p, bool) for p in row),
              "fidelity": lambda v: isinstance(v, str)}
    for key, ok in checks.items():
        if not all(ok(v) for v in generation[key]):
            raise InputError(source, f"{where}.{key}", "holds a value the search never writes "
                                                       "(not finite, or of the wrong type)")
    if not isinstance(generation.get("simulations"), int) or generation["simulations"] < 0:
        raise InputError(source, f"{where}.simulations", "must be a whole number >= 0")


__all__ = ["CHECKPOINT_FORMAT", "FIRST_ROUND", "FORMAT_FAMILY", "Round", "load", "read_round",
           "save"]

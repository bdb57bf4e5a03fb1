"""Shared helpers for the specification tests: writing input files and checking error messages.

Helpers are handed out as fixtures; constants a folder's tests share live in its conftest.py
and are imported from it (``from tests.recommender.conftest import FAST``: pyproject.toml puts
the repository on pytest's path).
"""

from __future__ import annotations

import copy
import gc
import json
import math
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from wrapenv.config import InputError
from wrapenv.material import Material
from wrapenv.wrap_elements import bend_factor

#: A LOAD.toml as a dict: EUR pallet, 2 columnar layers of explicitly sized PET bundles.
BASE_LOAD: dict[str, Any] = {
    "name": "spec load",
    "pallet": {"preset": "EUR"},
    "bundle": {"length_m": 0.28, "width_m": 0.19, "height_m": 0.33, "mass_kg": 9.3},
    "stack": {"layers": 2, "pattern": "columnar"},
}
#: Two PET bundles side by side on one layer: a load that simulates in a fraction of a second
#: (the commands' and the environment's tests run it).
TINY_LOAD: dict[str, Any] = {
    "name": "tiny",
    "pallet": {"preset": "EUR"},
    "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 1, "pattern": "explicit", "positions": [[-0.2, 0.0], [0.2, 0.0]]},
}


@pytest.fixture(autouse=True, scope="session")
def _from_the_repository_root() -> Iterator[None]:
    """The tests name the bundled examples as the README's commands do (`examples/...`), so
    they run from the repository's root wherever pytest was started."""
    started_in = Path.cwd()
    os.chdir(Path(__file__).resolve().parent.parent)
    yield
    os.chdir(started_in)


class Raw(str):
    """TOML text written as is (for values Python cannot express, or broken syntax)."""


def rss_kb() -> int:
    """This process's resident memory now (KiB; not ru_maxrss, its peak, which an earlier
    test's high-water mark would hide a leak under)."""
    gc.collect()
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024


def toml_value(value: Any) -> str:
    if isinstance(value, Raw):
        return str(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {value!r} as TOML")


def _table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def to_toml(data: dict[str, Any]) -> str:
    """Top-level scalars first, then one [table] per dict value (inline tables below that),
    then one [[array]] entry per dict of a list of dicts."""
    lines = [f"{k} = {toml_value(v)}" for k, v in data.items()
             if not isinstance(v, dict) and not _table_array(v)]
    for key, table in data.items():
        if isinstance(table, dict):
            lines.append(f"\n[{key}]")
            lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
    for key, items in data.items():
        if _table_array(items):
            for item in items:
                lines.append(f"\n[[{key}]]")
                lines += [f"{k} = {toml_value(v)}" for k, v in item.items()]
    return "\n".join(lines) + "\n"


def changed(base: dict[str, Any], changes: dict[str, Any] | None) -> dict[str, Any]:
    """A deep copy of `base` with dotted keys set (a number indexes a list, ``band.0.layers``);
    a value of None deletes the key."""
    data = copy.deepcopy(base)
    for dotted, value in (changes or {}).items():
        *parents, last = dotted.split(".")
        node: Any = data
        for part in parents:
            node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    return data


@pytest.fixture
def load_file(tmp_path: Path) -> Callable[..., Path]:
    """``load_file({"bundle.mass_kg": -1})`` writes BASE_LOAD with that change to tmp_path;
    ``load_file(text="...")`` writes the text as is; ``base=`` replaces BASE_LOAD."""

    def write(
        changes: dict[str, Any] | None = None,
        *,
        text: str | bytes | None = None,
        base: dict[str, Any] | None = None,
        name: str = "load.toml",
    ) -> Path:
        path = tmp_path / name
        if text is None:
            text = to_toml(changed(BASE_LOAD if base is None else base, changes))
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text)
        return path

    return write


#: A WRAP.toml as a dict: kraft, two bands.
BASE_WRAP: dict[str, Any] = {
    "material": "kraft",
    "web_width_m": 0.5,
    "band": [
        {"from_m": 0.0, "to_m": 0.45, "layers": 3, "tension_n": 250.0},
        {"from_m": 0.45, "to_m": 0.8, "layers": 1, "tension_n": 250.0},
    ],
}


#: A WRAP.toml with a machine program: Kraft, the contract's example.
BASE_PROGRAM: dict[str, Any] = {
    "material": "kraft",
    "web_width_m": 0.5,
    "program": {
        "bottom_wraps": 3, "bottom_from_m": 0.0, "bottom_tension_n": 400.0,
        "up_overlap": 0.5, "middle_tension_n": 250.0,
        "top_wraps": 2, "top_overhang_m": 0.05, "top_tension_n": 300.0,
        "down_overlap": 0.3, "rpm": 12.0,
        "reinforcement": [{"from_m": 0.40, "wraps": 2, "tension_n": 300.0}],
    },
}


@pytest.fixture
def wrap_data() -> Callable[[dict[str, Any] | None], dict[str, Any]]:
    """``wrap_data({"band.0.layers": 0})``: BASE_WRAP with that change, as parsed TOML."""

    def data(changes: dict[str, Any] | None = None) -> dict[str, Any]:
        return changed(BASE_WRAP, changes)

    return data


@pytest.fixture
def program_data() -> Callable[[dict[str, Any] | None], dict[str, Any]]:
    """``program_data({"program.top_wraps": 1})``: BASE_PROGRAM with that change, parsed."""

    def data(changes: dict[str, Any] | None = None) -> dict[str, Any]:
        return changed(BASE_PROGRAM, changes)

    return data


@pytest.fixture
def wrap_file(tmp_path: Path) -> Callable[..., Path]:
    """``wrap_file({"band.0.layers": 0})`` writes BASE_WRAP with that change to tmp_path;
    ``wrap_file(text="...")`` writes the text as is; ``program=True`` starts from BASE_PROGRAM
    instead."""

    def write(changes: dict[str, Any] | None = None, *, text: str | None = None,
              program: bool = False) -> Path:
        path = tmp_path / "wrap.toml"
        data = changed(BASE_PROGRAM if program else BASE_WRAP, changes)
        path.write_text(to_toml(data) if text is None else text)
        return path

    return write


@pytest.fixture
def assert_input_error() -> Callable[[BaseException, str, str], None]:
    """Check that an error is an `InputError` whose message is one line starting with
    ``source: field:`` (just ``source:`` when `field` is empty)."""

    def check(exc: BaseException, source: str, field: str) -> None:
        assert isinstance(exc, InputError), f"{type(exc).__name__}: {exc}"
        message = str(exc)
        assert "\n" not in message, f"message spans several lines: {message!r}"
        prefix = f"{source}: {field}: " if field else f"{source}: "
        assert message.startswith(prefix), f"{message!r} does not start with {prefix!r}"
        assert exc.source == source and exc.field == field
        assert exc.message.strip(), "the message must say what is wrong"

    return check


@pytest.fixture
def edge_factor() -> Callable[[Material, float], float]:
    """How much less tension a web bears wrapped fully round an edge of radius r: it bends to
    the edge's own curvature, so its outer fibre carries t / (2r + t) of strain on top of its
    membrane's (the hand computation `bend_curvature` and `bend_factor` must agree with)."""

    def factor(material: Material, edge_radius_m: float) -> float:
        t = material.layer_thickness_m
        return float(bend_factor(material, np.array(t / (2 * edge_radius_m + t))))

    return factor

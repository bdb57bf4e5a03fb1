"""`setup.toml` of a recording folder (CONTRACTS.md): the recording's frame rate, the camera's
mapping from world metres to pixels, the ArUco markers on the sled and the load, the template.

Read into `Setup` (every problem one `InputError` naming the file and the field) and written
back by `setup_toml` for synthetic recordings.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2

from wrapenv.config import InputError, Table, is_finite_number, write_atomic
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile

SETUP = "setup.toml"

#: setup.toml's `[recording]` key for the levels a unit ran before its take.
LEVELS_BEFORE = "levels_before_g"
#: At most this many levels before a take: a EUMOS sequence from 0.2 g to the bench's 1.02 g
#: has 9; each is simulated again in every replay of the take [A].
MAX_LEVELS_BEFORE = 20


def exact(value: float) -> str:
    """A float written so that it reads back equal."""
    return repr(float(value))


def aruco_dictionaries() -> tuple[str, ...]:
    """Names of OpenCV's predefined ArUco dictionaries (``DICT_4X4_50``, ...)."""
    return tuple(n for n in dir(cv2.aruco) if n.startswith("DICT_")
                 and isinstance(getattr(cv2.aruco, n), int))


@dataclass(frozen=True)
class MarkerPlacement:
    """One ArUco marker fixed to an object (printed on the web, bolted to the sled)."""

    id: int
    object: str                      # "sled", "pallet" or a bundle name "L2C1R1"
    #: marker centre minus object centre, in the object's frame (x along motion, z up), at rest
    offset_m: tuple[float, float]


@dataclass(frozen=True)
class MarkerSpec:
    dictionary: str                  # a cv2.aruco predefined dictionary name, "DICT_4X4_50"
    size_m: float | None             # side of the black square; None: not given (optional)
    placements: tuple[MarkerPlacement, ...]

    def aruco(self) -> cv2.aruco.Dictionary:
        return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))




@dataclass(frozen=True)
class Setup:
    """setup.toml (CONTRACTS.md): how the camera saw the bench (frame rate, scale, the sled's
    origin in the image), its markers and the bundles' template, checked in `parse`."""

    fps: float
    px_per_m: float
    origin_px: tuple[float, float]
    markers: MarkerSpec | None
    template: str | None
    template_field: str
    #: The levels (g) the unit ran on the bench before this take, in order (a lab's EUMOS
    #: sequence: one unit level after level); empty: a freshly stacked unit.
    levels_before_g: tuple[float, ...] = ()

    @classmethod
    def parse(cls, data: dict[str, Any], src: str) -> Setup:
        top = Table(data, src)
        template, where = None, "template"
        if top.has("template"):
            template = top.string("template")
        rec = top.table("recording", required=True)
        fps = rec.number("fps", positive=True)
        if rec.has("template"):
            template, where = rec.string("template"), "recording.template"
        before = _levels_before(rec) if rec.has(LEVELS_BEFORE) else ()
        rec.done()
        cam = top.table("camera", required=True)
        px_per_m = cam.number("px_per_m", positive=True)
        origin = _pair(cam, "origin_px")
        cam.done()
        markers = None
        if top.has("markers"):
            table = top.table("markers")
            if table.has("template"):
                template, where = table.string("template"), "markers.template"
            markers = _marker_spec(table)
        top.done()
        return cls(fps, px_per_m, origin, markers, template, where, before)


def _levels_before(t: Table) -> tuple[float, ...]:
    """`levels_before_g = [0.2, 0.3]`: numbers, then `check_levels_before`."""
    raw = t.array(LEVELS_BEFORE)
    for i, value in enumerate(raw):
        if not is_finite_number(value):
            raise t.error(LEVELS_BEFORE, f"must be levels in g (item {i}: {value!r})")
    return check_levels_before([float(v) for v in raw],
                               lambda message: t.error(LEVELS_BEFORE, message))


def check_levels_before(levels_g: Sequence[float],
                        error: Callable[[str], InputError]) -> tuple[float, ...]:
    """The levels a take's unit ran before it, as setup.toml and `synth` take them: at most
    `MAX_LEVELS_BEFORE`, each a level the bench runs (`PulseProfile`); `error(message)` is
    the InputError naming where they were given."""
    if len(levels_g) > MAX_LEVELS_BEFORE:
        raise error(f"at most {MAX_LEVELS_BEFORE} levels (got {len(levels_g)})")
    for i, level_g in enumerate(levels_g):
        try:
            PulseProfile(level_g)
        except InputError as exc:
            raise error(f"item {i} {exc.message}") from None
    return tuple(levels_g)


def _pair(t: Table, key: str) -> tuple[float, float]:
    """Two finite numbers, e.g. ``origin_px = [960.0, 1020.0]``."""
    raw = t.array(key)
    ok = len(raw) == 2 and all(map(is_finite_number, raw))
    if not ok:
        raise t.error(key, f"must be two finite numbers (got {raw!r})")
    return float(raw[0]), float(raw[1])


#: The largest marker side a setup may give: one printed for a sled's edge is a few centimetres
#: to a few decimetres; a larger figure is a unit slip.
MAX_MARKER_SIZE_M = 1.0
#: The dictionary a `[markers]` table that names none means: CONTRACTS.md's example, and the one
#: `synth` draws.
DEFAULT_DICTIONARY = "DICT_4X4_50"


def _marker_spec(t: Table) -> MarkerSpec:
    dictionary = t.string("dictionary", default=DEFAULT_DICTIONARY)
    names = aruco_dictionaries()
    if dictionary not in names:
        raise t.error("dictionary", f"unknown ArUco dictionary {dictionary!r} "
                                    f"(e.g. {DEFAULT_DICTIONARY})")
    size = t.number("size_m", positive=True, maximum=MAX_MARKER_SIZE_M) if t.has("size_m") else None
    placements = []
    raw = t.array("placement") if t.has("placement") else []
    for i, item in enumerate(raw):
        p = Table(item, t.source, t.field(f"placement[{i}]"))
        marker_id = p.integer("id", minimum=0)
        obj = p.string("object")
        offset = _pair(p, "offset_m")
        p.done()
        placements.append(MarkerPlacement(marker_id, obj, offset))
    t.done()
    return MarkerSpec(dictionary, size, tuple(placements))


def check_markers(spec: MarkerSpec, load: LoadUnit, src: str) -> None:
    """Ids the dictionary holds, each once, on objects the load has."""
    count = spec.aruco().bytesList.shape[0]
    objects = {"sled", "pallet"} | {b.name for b in load.layout().bundles}
    seen: set[int] = set()
    for i, p in enumerate(spec.placements):
        where = f"markers.placement[{i}]"
        if p.id >= count:
            raise InputError(src, f"{where}.id", f"{spec.dictionary} has ids 0 to {count - 1}"
                             f" (got {p.id})")
        if p.id in seen:
            raise InputError(src, f"{where}.id", f"duplicate marker id {p.id}")
        seen.add(p.id)
        if p.object not in objects:
            raise InputError(src, f"{where}.object", f"no object {p.object!r} in the load"
                             " (sled, pallet or a bundle name such as L1C1R1)")



def setup_toml(fps: float, px_per_m: float, origin_px: tuple[float, float],
               markers: MarkerSpec | None = None, template: str | None = None,
               levels_before_g: tuple[float, ...] = ()) -> str:
    """The setup.toml text (contract keys, template at the top level)."""
    lines = ["# Recording setup: side camera looking along +y, u = u0 + px_per_m x,"
             " v = v0 - px_per_m z."]
    if template is not None:
        lines.append(f"template = {json.dumps(template)}")
    lines += ["", "[recording]", f"fps = {exact(fps)}"]
    if levels_before_g:
        lines.append(f"{LEVELS_BEFORE} = [{', '.join(exact(g) for g in levels_before_g)}]")
    lines += ["", "[camera]", f"px_per_m = {exact(px_per_m)}",
              f"origin_px = [{exact(origin_px[0])}, {exact(origin_px[1])}]"]
    if markers is not None:
        lines += ["", "[markers]", f"dictionary = {json.dumps(markers.dictionary)}"]
        if markers.size_m is not None:
            lines.append(f"size_m = {exact(markers.size_m)}")
        for p in markers.placements:
            lines += ["", "[[markers.placement]]", f"id = {p.id}",
                      f"object = {json.dumps(p.object)}",
                      f"offset_m = [{exact(p.offset_m[0])}, {exact(p.offset_m[1])}]"]
    return "\n".join(lines) + "\n"


def write_setup(folder: str | Path, fps: float, px_per_m: float, origin_px: tuple[float, float],
                markers: MarkerSpec | None = None, template: str | None = None,
                levels_before_g: tuple[float, ...] = ()) -> None:
    write_atomic(Path(folder) / SETUP, setup_toml(fps, px_per_m, origin_px, markers, template,
                                                  levels_before_g).encode())


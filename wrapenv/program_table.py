"""WRAP.toml's [program] and [machine] tables (CONTRACTS.md): read and checked into
`wrapenv.program`'s `Program` and `Machine`, and written back.

wrapenv/wrap.py reads the rest of the file (material, web, bands) and calls these.
"""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from wrapenv.config import InputError, Table, fraction_hint
from wrapenv.material import MAX_PRESTRETCH, Material, check_tension
from wrapenv.program import TOP_OVERHANG_M, Machine, Program, Reinforcement

#: Rotation accepted: rotary-arm and ring wrappers reach a few tens of rpm; a turntable turns a
#: fragile load a few times a minute. Below 1 a figure is per second (0.2 for 12 rpm), and the
#: spiral would be laid as millions of revolutions.
MIN_RPM = 1.0
MAX_RPM = 100.0
#: Carriage speeds accepted: wrappers' carriages climb 0.05-0.2 m/s (docs/materials.md, M1).
MIN_CARRIAGE_SPEED_MPS = 0.01
MAX_CARRIAGE_SPEED_MPS = 2.0
#: Longest start or stop of the rotation accepted: a heavy turntable's is a few seconds.
MAX_RAMP_S = 60.0


def machine_from_table(t: Table) -> Machine:
    """WRAP.toml's [machine] table: the wrapper's speeds, ramps and handling time."""
    default = Machine()
    machine = Machine(
        rpm=_rpm(t, default.rpm),
        carriage_speed_mps=t.number("carriage_speed_mps", default.carriage_speed_mps,
                                    minimum=MIN_CARRIAGE_SPEED_MPS,
                                    maximum=MAX_CARRIAGE_SPEED_MPS),
        handling_s=t.number("handling_s", default.handling_s, minimum=0.0, maximum=3600.0),
        ramp_s=t.number("ramp_s", default.ramp_s, minimum=0.0, maximum=MAX_RAMP_S),
    )
    t.done()
    return machine


#: A height may lie this far beyond where it fits (rounding of heights in files) before it is
#: rejected.
FIT_TOLERANCE_M = 1e-3


def check_program_fits(program: Program, load_height_m: float, web_width_m: float,
                       source: str) -> None:
    """Heights a program names must lie on the load, and the bottom wraps no higher than the
    top ones (whose web's upper edge is `top_overhang_m` above the load): a reinforcement may
    lie anywhere on the load, the carriage travelling to it (CONTRACTS.md's example parks one
    above the top wraps' carriage height)."""
    h = load_height_m
    b0 = program.bottom_from_m
    if b0 >= h:
        raise InputError(source, "program.bottom_from_m", f"{b0} m is not below the top of the "
                         f"load ({h:.3f} m)")
    top = program.top_from_m(web_width_m, h)
    if b0 > top + FIT_TOLERANCE_M:
        raise InputError(source, "program.bottom_from_m",
                         f"{b0} m is above where the top wraps are laid ({top:.3f} m, a "
                         f"{web_width_m} m web on a {h:.3f} m load): the carriage rises from "
                         "the bottom wraps to the top ones")
    for i, r in enumerate(program.reinforcements):
        if r.from_m >= h:
            raise InputError(source, f"program.reinforcement[{i}].from_m",
                             f"{r.from_m} m is outside the load (0 to {h:.3f} m)")


#: Overlaps are fractions of the web; gaps up to a web wide (>= -1), and at most 0.9 [A]: a
#: spiral at 0.9 lays 10 layers in one pass (the search goes to 0.75, 4 layers), at 0.99 it
#: laid 71 and 12 kg of paper on the 2-layer example; layers beyond that are parked wraps.
MIN_OVERLAP, MAX_PROGRAM_OVERLAP = -1.0, 0.9
#: Most revolutions parked at one height (bottom, top, a reinforcement) [A]: three times the
#: search's six (`wrapenv.design.MAX_WRAPS`); a wrapper's program lays a few. Thirty top wraps
#: of 800 N needed four times the bench's solver iterations to rest (docs/bench.md); 100000
#: were a typo, costed 17 t of web and thrown apart by the bench (docs/materials.md, section 6).
MAX_WRAPS_AT_ONE_HEIGHT = 20


def program_from_table(t: Table, material: Material, web_width_m: float) -> Program:
    """Validate WRAP.toml's [program] table (CONTRACTS.md): wraps, overlaps, tensions, heights
    that can be checked without the load; `check_program_fits` does the rest."""
    film = material.kind == "film"
    program = Program(
        bottom_wraps=t.integer("bottom_wraps", minimum=0, maximum=MAX_WRAPS_AT_ONE_HEIGHT),
        bottom_from_m=t.number("bottom_from_m", 0.0, minimum=0.0),
        bottom_tension_n=check_tension(t, "bottom_tension_n", material, web_width_m),
        up_overlap=_overlap(t, "up_overlap"),
        middle_tension_n=check_tension(t, "middle_tension_n", material, web_width_m),
        top_wraps=t.integer("top_wraps", minimum=0, maximum=MAX_WRAPS_AT_ONE_HEIGHT),
        top_overhang_m=_overhang(t, web_width_m),
        top_tension_n=check_tension(t, "top_tension_n", material, web_width_m),
        down_overlap=_overlap(t, "down_overlap") if t.has("down_overlap") else None,
        rpm=_rpm(t) if t.has("rpm") else None,
        reinforcements=tuple(
            _reinforcement(Table(item, t.source, f"{t.field('reinforcement')}[{i}]"), material,
                           web_width_m)
            for i, item in enumerate(t.array("reinforcement") if t.has("reinforcement") else [])),
        roping=t.boolean("roping", False),
        prestretch=(t.number("prestretch", minimum=0.0, maximum=MAX_PRESTRETCH)
                    if t.has("prestretch") else None),
    )
    if program.roping and not film:
        raise t.error("roping", f"{material.name} is not roped: only film gathers into a rope")
    if program.prestretch is not None and material.prestretch is None:
        raise t.error("prestretch", f"{material.name} is not pre-stretched")
    t.done()
    return program


def _overlap(t: Table, key: str) -> float:
    value = t.number(key, minimum=MIN_OVERLAP)
    if value > MAX_PROGRAM_OVERLAP:
        why = (f"a spiral at {value:g} lays {1 / (1 - value):.0f} layers in one pass, which "
               "parked wraps lay" if value < 1.0 else "at 1 or more the carriage never rises")
        raise t.error(key, f"must be at most {MAX_PROGRAM_OVERLAP}: {why} (got {value})"
                      f"{fraction_hint(value, ' of the web')}")
    return value


def _rpm(t: Table, default: float | None = None) -> float:
    value = t.number("rpm", default, positive=True, maximum=MAX_RPM)
    if value < MIN_RPM:
        raise t.error("rpm", f"must be >= {MIN_RPM:g} (got {value:g}): revolutions per minute, "
                             "not per second (0.2 a second is 12 rpm)")
    return value


def _overhang(t: Table, web_width_m: float) -> float:
    value = t.number("top_overhang_m", TOP_OVERHANG_M, minimum=0.0)
    if value >= web_width_m:
        raise t.error("top_overhang_m", f"must be below the web width ({web_width_m} m): the top "
                      f"wraps would lay nothing on the load (got {value})")
    return value


def _reinforcement(t: Table, material: Material, web_width_m: float) -> Reinforcement:
    r = Reinforcement(from_m=t.number("from_m", minimum=0.0),
                      wraps=t.integer("wraps", minimum=1, maximum=MAX_WRAPS_AT_ONE_HEIGHT),
                      tension_n=check_tension(t, "tension_n", material, web_width_m))
    t.done()
    return r


def program_to_dict(program: Program) -> dict[str, Any]:
    """WRAP.toml's [program] table, optional keys only when they are set."""
    out = {k: v for k, v in asdict(program).items()
           if k not in ("reinforcements", "roping") and v is not None}
    if program.roping:
        out["roping"] = True
    if program.reinforcements:
        out["reinforcement"] = [asdict(r) for r in program.reinforcements]
    return out

"""The wrap: material cards, and what WRAP.toml describes — a machine program or bands of layers.

A `WrapFormat` is plain data (no physics). Its `bands` are the layer map the bench turns into a
membrane (`layers_over`, `line_tension_n_per_m`); its `passes` are what a spiral wrapper does to
lay it (wrapenv.program), from which come the material used and the cycle time. A WRAP.toml
holds either a `[program]` (what `recommend` writes and an operator enters: its bands are the
web the machine really lays) or `[[band]]`s (a physics experiment: the layers as given, costed
as the full-width revolutions a machine would need for them).

In WRAP.toml, ``material = "kraft"`` or ``"lldpe"`` names a card of docs/materials.md; a custom
material is written as a ``[material]`` table of its values instead (TOML cannot hold both
``material = "custom"`` and a ``[material]`` table, they are the same key).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from itertools import groupby
from pathlib import Path
from typing import Any

import tomli_w

from wrapenv.config import InputError, Table, read_toml
from wrapenv.load import Layout
from wrapenv.load_checks import MAX_LOAD_HEIGHT_M
from wrapenv.material import (
    MATERIALS,
    Material,
    check_hours_since_wrapping,
    check_tension,
    custom_material,
)
from wrapenv.program import (
    Band,
    Machine,
    Outline,
    Pass,
    Program,
    as_laid,
    band_passes,
    cycle_time_s,
    layer_map,
    pass_area_m2,
)
from wrapenv.program_table import (
    FIT_TOLERANCE_M,
    check_program_fits,
    machine_from_table,
    program_from_table,
    program_to_dict,
)

__all__ = ["MATERIALS", "Band", "Material", "MaterialUsed", "Program",
           "Web", "WrapFormat", "program_to_dict"]

#: Web widths accepted: machine webs are 0.5 m, wide paper rolls about 1 m; the narrowest
#: banding film about 0.1 m. Outside them a width is a slip of units, and a narrow one would
#: have a band laid as millions of revolutions (docs/materials.md, section 6).
MIN_WEB_WIDTH_M = 0.05
MAX_WEB_WIDTH_M = 2.0
#: The web most spiral wrappers run (docs/materials.md, section 4).
DEFAULT_WEB_WIDTH_M = 0.5
#: The warning for a paper program with no bottom wrap: the clamp lets the web's head go after
#: the first revolution and paper does not cling, so a travelling first revolution leaves the
#: head free. The bench does not model a free head: it judges the web as if held.
UNHELD_HEAD = ("program.bottom_wraps = 0: nothing holds the web's head (paper does not cling; the"
               " clamp lets go after the first revolution); the bench judges it as if held")
#: Height step at which a program's layers are checked for a web that does not close.
OPEN_STEP_M = 0.005
#: A tension under this share of the web's yield force holds nothing (the search's least is 5 %,
#: machines pull at up to half): most likely a figure in kilonewtons.
SLACK_TENSION_FRACTION = 0.01


@dataclass(frozen=True)
class MaterialUsed:
    """The web a wrap costs."""

    area_m2: float         # web laid: every revolution's length x the web width
    mass_kg: float
    web_length_m: float    # web laid, metres: area / web width
    roll_length_m: float   # web taken from the roll: laid / (1 + pre-stretch) for film
    revolutions: float


@dataclass(frozen=True)
class Web:
    """The web a machine runs, for which a program is sought: its card, its width, and the
    machine's settings that time a cycle."""

    material: Material
    material_key: str = "custom"   # a card of MATERIALS by name, or "custom"
    width_m: float = DEFAULT_WEB_WIDTH_M
    machine: Machine = Machine()

    @classmethod
    def named(cls, key: str) -> Web:
        """A named card on the default web and machine."""
        if key not in MATERIALS:
            raise InputError("arguments", "material",
                             f"must be one of {', '.join(map(repr, MATERIALS))} (got {key!r})")
        return cls(MATERIALS[key], key)

    @classmethod
    def from_toml(cls, path: str | Path) -> Web:
        """The web of a WRAP.toml: `material` or a `[material]` table, `web_width_m` and an
        optional `[machine]`. A program or bands it holds (the file may be the program a
        machine runs today) are checked as any WRAP.toml's, since a typo there is one in what
        the machine lays, but not used."""
        top = Table(read_toml(path), str(path))
        web = _web(top)
        _program_or_bands(top, web)
        top.done()
        return web

    def identity(self) -> str | dict[str, Any]:
        """What tells two webs apart in a search's checkpoint: a named card's name on the
        default web and machine, else everything."""
        if self.material_key in MATERIALS and self == Web.named(self.material_key):
            return self.material_key
        return {"material": asdict(self.material), "material_key": self.material_key,
                "width_m": self.width_m, "machine": asdict(self.machine)}


@dataclass(frozen=True)
class WrapFormat:
    """A wrap as the bench simulates it (`bands`) and as a machine lays it (`passes`)."""

    material: Material
    web_width_m: float
    bands: tuple[Band, ...]  # the band form: in file order, so band[i] in messages is the file's
    material_key: str = "custom"  # "kraft" | "lldpe" | "custom": what the file said
    program: Program | None = None  # the program that laid the bands (None: the band form)
    machine: Machine = Machine()
    passes: tuple[Pass, ...] = field(default=())

    def __post_init__(self) -> None:
        if self.program is None and not self.passes:
            object.__setattr__(self, "passes", band_passes(self.bands, self.web_width_m))

    @classmethod
    def from_program(cls, material: Material, web_width_m: float, program: Program,
                     load_height_m: float, material_key: str = "custom",
                     machine: Machine | None = None) -> WrapFormat:
        """The wrap a program lays on a load of this height, at its machine's speeds
        (`as_laid`)."""
        machine = machine or Machine()
        rpm = program.rpm if program.rpm is not None else machine.rpm
        passes = as_laid(program.passes(web_width_m, load_height_m), rpm, machine)
        return cls(material, web_width_m, layer_map(passes, web_width_m, load_height_m),
                   material_key, program, machine, passes)

    # --- reading and writing -----------------------------------------------------------------

    @classmethod
    def from_toml(cls, path: str | Path, load_height_m: float | None = None) -> WrapFormat:
        return cls.from_dict(read_toml(path), str(path), load_height_m)

    @classmethod
    def from_dict(
        cls, data: dict[str, Any], source: str = "wrap", load_height_m: float | None = None
    ) -> WrapFormat:
        """Validate a parsed WRAP.toml. Bands are named ``band[i]`` in errors, i counting the
        ``[[band]]`` tables from 0 in file order. With `load_height_m`, also `check_fits`; a
        program needs it (its top wraps are placed from the load's top)."""
        top = Table(data, source)
        web = _web(top)
        body = _program_or_bands(top, web)
        top.done()
        if isinstance(body, Program):
            if load_height_m is None:
                raise ValueError("a wrapping program needs the load's height to be laid")
            check_program_fits(body, load_height_m, web.width_m, source)
            return cls.from_program(web.material, web.width_m, body, load_height_m,
                                    web.material_key, web.machine)
        if body is None:
            raise top.error("program", "missing: a WRAP.toml holds a [program] (what the machine "
                                       "lays) or [[band]]s; this one only names a web")
        wrap = cls(web.material, web.width_m, body, web.material_key, machine=web.machine)
        if load_height_m is not None:
            wrap.check_fits(load_height_m, source)
        return wrap

    def check_fits(self, load_height_m: float, source: str) -> None:
        """Reject bands reaching above the load: there is nothing there to hold the web."""
        if self.program is not None:
            check_program_fits(self.program, load_height_m, self.web_width_m, source)
            return
        for i, band in enumerate(self.bands):
            if band.to_m > load_height_m + FIT_TOLERANCE_M:
                raise InputError(source, f"band[{i}].to_m", f"{band.to_m} m is above the top of"
                                 f" the load ({load_height_m:.3f} m)")

    def warnings(self, layout: Layout | None = None) -> tuple[str, ...]:
        """What the file asks that no machine lays or the bench cannot judge: a tension too
        slack to hold anything (a figure in kilonewtons?) or beyond the web's yield; paper
        bands narrower than the web (only a rope of film is narrower, and paper is not roped);
        a paper program without a bottom wrap, whose head nothing holds; a program whose web
        does not close round the load at some height (wrapenv.design), whose spiral the
        carriage cannot rise at the machine's rpm, or, on a `layout`, whose web misses the
        pallet or lies mostly above the load."""
        slack = self._tension_warnings()
        if self.program is not None:
            placed = (_placement_warnings(self.program, self.web_width_m, layout)
                      if layout is not None else ())
            return (slack + self._program_warnings(self.program)
                    + self._carriage_warnings(self.program) + placed)
        if self.material.kind != "paper":
            return slack
        return slack + tuple(
            f"band[{i}] is {b.height_m:.3f} m tall, narrower than the {self.web_width_m} m web: "
            "no machine lays it (material is costed as full-width revolutions)"
            for i, b in enumerate(self.bands) if b.height_m < self.web_width_m - 1e-9)

    def _tension_warnings(self) -> tuple[str, ...]:
        """A warning for each tension under `SLACK_TENSION_FRACTION` of the web's yield force,
        and for each above it (between yield and break: accepted, as the web bears it)."""
        yield_n = self.material.yield_force_n_per_m * self.web_width_m
        if self.program is not None:
            p = self.program
            named = [("program.bottom_tension_n", p.bottom_tension_n),
                     ("program.middle_tension_n", p.middle_tension_n),
                     ("program.top_tension_n", p.top_tension_n),
                     *((f"program.reinforcement[{i}].tension_n", r.tension_n)
                       for i, r in enumerate(p.reinforcements))]
        else:
            named = [(f"band[{i}].tension_n", b.tension_n) for i, b in enumerate(self.bands)]
        share = f"{100 * SLACK_TENSION_FRACTION:g} %"
        slack = tuple(f"{key} is {value:g} N, under {share} of the web's yield force "
                      f"({yield_n:.0f} N): kilonewtons? Tensions are in newtons"
                      for key, value in named if value < SLACK_TENSION_FRACTION * yield_n)
        return slack + tuple(
            f"{key} is {value:g} N, above the web's yield force ({yield_n:.0f} N): the web is "
            "stretched for good while it is laid, and a corner's peak tears it first; machines "
            f"keep about half of it ({yield_n / 2:.0f} N, docs/materials.md, P4)"
            for key, value in named if value > yield_n)

    def _carriage_warnings(self, program: Program) -> tuple[str, ...]:
        """A spiral asking a rise per revolution the carriage cannot travel at the rpm is laid
        at the overlap the carriage allows (`as_laid`): said, as the material counts it."""
        if not any(p.travel_m > 0 for p in self.passes):
            return ()
        most = self.machine.most_rise_m(self.rpm)
        asked = [("program.up_overlap", program.up_overlap)]
        if program.down_overlap is not None:
            asked.append(("program.down_overlap", program.down_overlap))
        return tuple(
            f"{key} = {overlap:g} asks the carriage to rise {self.web_width_m * (1 - overlap):.3f}"
            f" m a revolution; at {self.rpm:g} rpm it rises at most {most:.3f} m "
            f"({self.machine.carriage_speed_mps:g} m/s), so the spiral is laid at "
            f"{100 * (1 - most / self.web_width_m):.0f} % overlap, and the web used counts it so"
            for key, overlap in asked if self.web_width_m * (1 - overlap) > most + 1e-9)

    def _program_warnings(self, program: Program) -> tuple[str, ...]:
        out = [UNHELD_HEAD] if self.material.kind == "paper" and program.bottom_wraps == 0 else []
        top = max((b.to_m for b in self.bands), default=0.0)
        steps = int((top - program.bottom_from_m) / OPEN_STEP_M)
        heights = (program.bottom_from_m + k * OPEN_STEP_M for k in range(steps))
        # each stretch on its own: a spiral alone is open at both ends, closed between them
        stretches = [list(run) for is_open, run in
                     groupby(heights, key=lambda z: 1e-9 < self.layers_at(z) < 1 - 1e-9)
                     if is_open]
        if stretches:
            where = " and ".join(f"from {run[0]:.2f} to {run[-1] + OPEN_STEP_M:.2f} m"
                                 for run in stretches)
            out.append(f"the web does not close round the load {where} (less than one layer: "
                       "part of a spiral turn, which the bench averages round the load); raise "
                       "the spiral's overlap, or add a reinforcement wrap there")
        return tuple(out)

    def _material_entry(self) -> str | dict[str, Any]:
        """The card's name, or the card in full when it is not a named card (e.g. `scaled`)."""
        named = MATERIALS.get(self.material_key) == self.material
        if named:
            return self.material_key
        out = {k: v for k, v in asdict(self.material).items() if v is not None}
        # its relaxation always (a custom card that gives none takes its kind's), as TOML holds it
        law = self.material.relaxation
        out["relaxation"] = {"plateau": law.plateau, "terms": [list(t) for t in law.terms]}
        return out

    def to_dict(self) -> dict[str, Any]:
        """The WRAP.toml content (what `from_dict` reads back): the program, or the bands."""
        out: dict[str, Any] = {"material": self._material_entry(),
                               "web_width_m": self.web_width_m}
        if self.machine != Machine():
            out["machine"] = asdict(self.machine)
        if self.program is not None:
            out["program"] = program_to_dict(self.program)
        else:
            out["band"] = [_band_dict(b) for b in self.bands]
        return out

    def to_json(self) -> dict[str, Any]:
        """What a report says of the wrap: the card, the program (if any) and the bands it
        simulated."""
        out: dict[str, Any] = {"material": self._material_entry(),
                               "web_width_m": self.web_width_m,
                               "bands": [_band_dict(b, rounded=True) for b in self.bands]}
        if self.machine != Machine():
            out["machine"] = asdict(self.machine)
        if self.program is not None:
            out["program"] = program_to_dict(self.program)
        return out

    def to_toml(self) -> str:
        head = ("# Wrap (WRAP.toml): heights in metres from the sled surface (a program's: the "
                "web's lower edge),\n# tensions in newtons per layer of web while wrapping, "
                "overlaps as fractions of the web (0.5 = 50 %).\n")
        return head + tomli_w.dumps(self.to_dict())

    # --- variants ------------------------------------------------------------------------------

    def scaled(self, stiffness_scale: float = 1.0, tension_scale: float = 1.0) -> WrapFormat:
        """The wrap as a calibration corrects it: stiffer or softer web, other tensions (the
        program, what the machine is set to, stays as it is)."""
        material = replace(
            self.material, stiffness_n_per_m=self.material.stiffness_n_per_m * stiffness_scale)
        bands = tuple(replace(b, tension_n=b.tension_n * tension_scale) for b in self.bands)
        return replace(self, material=material, bands=bands)

    def relaxed(self, hours: float, loss_scale: float = 1.0) -> WrapFormat:
        """The wrap after standing `hours` since wrapping: every band's tension scaled by the
        material's relaxation law (the web's length and stiffness are what they were). With a
        `loss_scale` (an uncertainty sample's draw), the tension the law loses is scaled by it,
        never past all of it; at 1 the law's own share is kept exactly."""
        check_hours_since_wrapping(hours)
        kept = self.material.relaxation.retained(hours)
        if loss_scale != 1.0:
            kept = 1.0 - min(1.0, (1.0 - kept) * loss_scale)
        return replace(self, bands=tuple(replace(b, tension_n=b.tension_n * kept)
                                         for b in self.bands))

    # --- what the membrane sees ----------------------------------------------------------------

    def layers_at(self, z_m: float) -> float:
        """Layers of web at height z, averaged round the load."""
        return sum(b.layers_at(z_m) for b in self.bands)

    def layers_over(self, z0_m: float, z1_m: float) -> float:
        """Average number of web layers over [z0, z1]; overlapping bands add up."""
        return sum(b.layer_metres(z0_m, z1_m) for b in self.bands) / _span(z0_m, z1_m)

    def line_tension_n_per_m(self, z0_m: float, z1_m: float) -> float:
        """Average hoop pretension over [z0, z1], newtons per metre of height."""
        total = sum(b.tension_n * b.layer_metres(z0_m, z1_m) for b in self.bands)
        return total / self.web_width_m / _span(z0_m, z1_m)

    def covers(self, z0_m: float, z1_m: float) -> bool:
        return any(b.layer_metres(z0_m, z1_m) > 1e-12 for b in self.bands)

    # --- what it costs -------------------------------------------------------------------------

    @property
    def prestretch(self) -> float | None:
        """The film's pre-stretch as laid: the program's, else the card's (None: the web is not
        pre-stretched)."""
        given = self.program.prestretch if self.program is not None else None
        return given if given is not None else self.material.prestretch

    def material_used(self, outline: Outline) -> MaterialUsed:
        """The web every revolution lays (round the pallet below its top, round the load
        above), its mass, and the metres taken from the roll."""
        area = sum(pass_area_m2(p, self.web_width_m, outline) for p in self.passes)
        laid = area / self.web_width_m
        return MaterialUsed(
            area_m2=area,
            mass_kg=area * self.material.grammage_at(self.prestretch),
            web_length_m=laid,
            roll_length_m=laid / (1 + (self.prestretch or 0.0)),
            revolutions=sum(p.turns for p in self.passes),
        )

    def material_used_on(self, layout: Layout) -> MaterialUsed:
        """`material_used` for a laid-out unit: round its pallet, then round its bundles."""
        return self.material_used(outline_of(layout))

    @property
    def rpm(self) -> float:
        """The speed the program asks, else the machine's."""
        if self.program is not None and self.program.rpm is not None:
            return self.program.rpm
        return self.machine.rpm

    @property
    def cycle_time_s(self) -> float:
        """Seconds from one pallet to the next on this machine (wrapenv.program.cycle_time_s)."""
        home = self.program.bottom_from_m if self.program is not None else 0.0
        return cycle_time_s(self.passes, home, self.rpm, self.machine)

    @property
    def pallets_per_hour(self) -> float:
        """The machine's throughput on this program, one pallet a cycle."""
        return 3600.0 / self.cycle_time_s


def _placement_warnings(program: Program, web_width_m: float, layout: Layout
                        ) -> tuple[str, ...]:
    """A program whose web misses the pallet (nothing ties the load to it), or whose top wraps
    or reinforcements lay most of their web above the load (folded over: the file asked it,
    or the web is wider than the load is high)."""
    pallet_m, h, w = layout.pallet_size_m[2], layout.load_height_m, web_width_m
    out = []
    if program.bottom_from_m >= pallet_m:
        out.append(f"program.bottom_from_m = {program.bottom_from_m:g} m: the web does not reach "
                   f"down to the pallet (its top at {pallet_m:.3f} m), so nothing ties the load "
                   "to it")
    above = program.top_from_m(w, h) + w - h
    if program.top_wraps and above > program.top_overhang_m + 1e-9:
        out.append(f"web_width_m = {w:g} m is more than the load's height ({h:.3f} m) and "
                   f"program.top_overhang_m ({program.top_overhang_m:g} m): the top wraps are "
                   f"laid from the sled and reach {above:.2f} m above the load, folded over it")
    elif program.top_wraps and above > w / 2:
        out.append(f"program.top_overhang_m = {program.top_overhang_m:g} m: the top wraps lay "
                   f"{above:.2f} m of their {w:g} m web above the load, folded over it")
    out.extend(f"program.reinforcement[{i}].from_m = {r.from_m:g} m: its wraps lay "
               f"{r.from_m + w - h:.2f} m of their {w:g} m web above the load, folded over it"
               for i, r in enumerate(program.reinforcements) if r.from_m + w - h > w / 2)
    return tuple(out)


def outline_of(layout: Layout) -> Outline:
    """The perimeters a revolution goes round on this unit."""
    px, py, pz = layout.pallet_size_m
    lx, ly = layout.outline_m
    return Outline(pz, 2 * (px + py), 2 * (lx + ly))


def _span(z0: float, z1: float) -> float:
    if not z1 > z0:
        raise ValueError(f"height interval [{z0}, {z1}] is empty")
    return z1 - z0


def _band_dict(band: Band, rounded: bool = False) -> dict[str, Any]:
    """A band as WRAP.toml writes it (exact), or for reports (`rounded`: heights to 1e-6 m,
    layer counts to 1e-4, as a program's bands come out of sums of fractions)."""
    out = asdict(band)
    if band.layers_to is None:
        del out["layers_to"]
    if rounded:
        out.update({k: round(out[k], 6) for k in ("from_m", "to_m")})
        out.update({k: _whole(round(out[k], 4)) for k in ("layers", "layers_to") if k in out})
    return out


def _whole(x: float) -> float | int:
    """Whole layer counts written as integers, so a band form reads back as written."""
    return int(x) if float(x).is_integer() else x


def _web(top: Table) -> Web:
    """A WRAP.toml's card, web width and machine."""
    key, material = _material(top)
    width = top.number("web_width_m", minimum=MIN_WEB_WIDTH_M, maximum=MAX_WEB_WIDTH_M)
    return Web(material, key, width, machine_from_table(top.table("machine")))


def _material(top: Table) -> tuple[str, Material]:
    if isinstance(top.data.get("material"), dict):
        return "custom", custom_material(top.table("material"))
    key = top.string("material")
    if key == "custom":
        raise top.error("material", "a custom material is written as a [material] table"
                        " of its values, in place of material = \"custom\"")
    if key not in MATERIALS:
        raise top.error("material", f"must be one of {', '.join(map(repr, MATERIALS))}, or a "
                        f"[material] table of a custom material's values (got {key!r})")
    return key, MATERIALS[key]


#: Most layers a [[band]] gives [A]: above what a program of the most wraps lays at one height
#: (bottom and reinforcement wraps of `MAX_WRAPS_AT_ONE_HEIGHT` each, 40, and a spiral of
#: `MAX_PROGRAM_OVERLAP`'s ten layers), a round figure with room for a hand-made band.
MAX_BAND_LAYERS = 100


def _program_or_bands(top: Table, web: Web) -> Program | tuple[Band, ...] | None:
    """A WRAP.toml's [program] or its [[band]]s, validated (None: it names only a web)."""
    if top.has("program"):
        if top.has("band"):
            raise top.error("program", "a WRAP.toml holds either [program] or [[band]]s, "
                                       "not both")
        return program_from_table(top.table("program"), web.material, web.width_m)
    if not top.has("band"):
        return None
    raw = top.array("band")
    if not raw:
        raise top.error("band", "must list at least one [[band]]")
    return tuple(_band(Table(item, top.source, f"band[{i}]"), web.material, web.width_m)
                 for i, item in enumerate(raw))


def _band(t: Table, material: Material, web_width_m: float) -> Band:
    from_m = t.number("from_m", minimum=0.0, maximum=MAX_LOAD_HEIGHT_M)
    to_m = t.number("to_m", maximum=MAX_LOAD_HEIGHT_M)
    if to_m <= from_m:
        raise t.error("to_m", f"must be above from_m ({from_m} m) (got {to_m})")
    layers = t.integer("layers", minimum=1, maximum=MAX_BAND_LAYERS)
    tension = check_tension(t, "tension_n", material, web_width_m)
    t.done()
    return Band(from_m, to_m, layers, tension)

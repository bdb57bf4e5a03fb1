"""The wrap format: material cards, bands of web layers, material used and the machine recipe.

A `WrapFormat` is what a WRAP.toml describes. It is plain data (no physics): the bench turns it
into a membrane through `layers_over` and `line_tension_n_per_m`, the recommender searches over
it, and `machine_recipe` restates it in the terms a spiral wrapping machine is set up in.
Heights are measured from the sled surface (the underside of the pallet is z = 0).

In WRAP.toml, ``material = "kraft"`` or ``"lldpe"`` names a card of docs/materials.md; a custom
material is written as a ``[material]`` table of its values instead (TOML cannot hold both
``material = "custom"`` and a ``[material]`` table, they are the same key).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from wrapenv.config import InputError, Table, read_toml
from wrapenv.load import Layout

#: Largest web width accepted; machine webs are 0.5 m, wide paper rolls about 1 m.
MAX_WEB_WIDTH_M = 2.0
#: Strains at or above this are typos (1000 %), not materials.
MAX_STRAIN = 10.0
#: A band may end this far above the load (rounding of heights in files) before it is rejected.
FIT_TOLERANCE_M = 1e-3
#: A band starting at or below this height wraps the pallet (EUR pallet 0.144 m): the bottom zone.
BOTTOM_ZONE_MAX_M = 0.15
#: Slack when comparing a band height with the web width, so 0.95 - 0.45 still fits one web.
_HEIGHT_EPS_M = 1e-9


@dataclass(frozen=True)
class Material:
    """One layer of web as applied: bilinear (elastic, then linear hardening) in tension, MD."""

    name: str
    grammage_kg_m2: float  # mass per m² of one layer as applied
    stiffness_n_per_m: float  # MD force per metre of web width per unit strain, one layer
    yield_strain: float  # end of the elastic part (strain past it is permanent)
    break_strain: float  # the web tears here
    hardening_ratio: float = 0.1  # post-yield tangent stiffness / stiffness_n_per_m
    cd_ratio: float = 0.5  # cross-direction (vertical) stiffness / MD stiffness

    @property
    def yield_force_n_per_m(self) -> float:
        return self.stiffness_n_per_m * self.yield_strain

    @property
    def break_force_n_per_m(self) -> float:
        hardening = self.hardening_ratio * self.stiffness_n_per_m
        return self.yield_force_n_per_m + hardening * (self.break_strain - self.yield_strain)


#: The cards of docs/materials.md (labels there: [S] sourced, [D] derived, [A] assumed).
MATERIALS: dict[str, Material] = {
    "kraft": Material(  # section 1, extensible sack kraft (Mondi Advantage StretchWrap class)
        name="kraft stretch paper",
        grammage_kg_m2=0.090,  # [S] 80-120 g/m² pallet wrapping paper
        stiffness_n_per_m=4.0e5,  # [D] P1: TSI 4.5 kNm/g x 90 g/m² ≈ 3.0 GPa x 130 µm
        yield_strain=0.008,  # [A] P2: short, nearly linear MD curve
        break_strain=0.07,  # [S] extensible kraft 4-9 %
        hardening_ratio=0.1125,  # [D] P2: tangent 45 kN/m / 4e5 -> breaks at ≈ 6.0 kN/m (P3)
        cd_ratio=0.6,  # [A] CD strength 4000 N/m / MD 6000 N/m, rounded down
    ),
    "lldpe": Material(  # card 2b, cast film as applied after 250 % pre-stretch
        name="LLDPE cast stretch film (applied)",
        grammage_kg_m2=0.0098,  # [D] 920 kg/m³ x 10.7 µm (t = 20 µm / √3.5)
        stiffness_n_per_m=2500.0,  # [D]/[A] L2: 240 MPa x 10.7 µm
        yield_strain=0.15,  # [D]/[A] L3: re-yield at the pre-stretch flow stress
        break_strain=0.55,  # [D] (1 + 4.5) / 3.5 - 1, rounded down
        hardening_ratio=0.925,  # [D] strength 1300 N/m: (1300 - 375) / (2500 x 0.4)
        cd_ratio=0.5,  # [A] no public figure
    ),
}
#: Web tension per layer for a 0.5 m web, newtons: [A] P4 (paper), [S] L4 (film).
DEFAULT_TENSION_N: dict[str, float] = {"kraft": 250.0, "lldpe": 70.0}


@dataclass(frozen=True)
class Band:
    """A height range wrapped with `layers` layers of web, each pulled at `tension_n`."""

    from_m: float
    to_m: float
    layers: int
    tension_n: float

    @property
    def height_m(self) -> float:
        return self.to_m - self.from_m

    def overlap_m(self, z0: float, z1: float) -> float:
        """Length of this band inside [z0, z1] (0 when they do not meet)."""
        return max(0.0, min(self.to_m, z1) - max(self.from_m, z0))


@dataclass(frozen=True)
class MaterialUsed:
    area_m2: float
    mass_kg: float
    length_m: float  # web length off the roll: area / web width


@dataclass(frozen=True)
class RecipeRow:
    """One zone of the machine program. ``passes == 0``: the carriage stays at `carriage_m`."""

    zone: str  # "bottom" | "middle" | "top"
    from_m: float
    to_m: float
    carriage_m: float  # height of the web's lower edge when the zone starts
    revolutions: int  # turntable revolutions spent on this zone
    passes: int
    tension_n: float


@dataclass(frozen=True)
class Recipe:
    """A wrap format as a spiral wrapper is set: wraps at parked carriage and carriage passes."""

    web_width_m: float
    rows: tuple[RecipeRow, ...]

    def _parked(self, zone: str) -> int:
        return sum(r.revolutions for r in self.rows if r.zone == zone and r.passes == 0)

    @property
    def bottom_wraps(self) -> int:
        """Revolutions with the carriage parked on the bottom zone (0 if it needs passes)."""
        return self._parked("bottom")

    @property
    def top_wraps(self) -> int:
        return self._parked("top")

    @property
    def carriage_passes(self) -> int:
        return sum(r.passes for r in self.rows)

    @property
    def revolutions(self) -> int:
        return sum(r.revolutions for r in self.rows)

    def table(self) -> str:
        head = (f"{'zone':<8}{'from m':>8}{'to m':>8}{'carriage m':>12}{'revolutions':>13}"
                f"{'passes':>8}{'tension N':>11}")
        lines = [head]
        for r in self.rows:
            lines.append(f"{r.zone:<8}{r.from_m:>8.3f}{r.to_m:>8.3f}{r.carriage_m:>12.3f}"
                         f"{r.revolutions:>13d}{r.passes:>8d}{r.tension_n:>11.1f}")
        lines.append(f"web {self.web_width_m:.3f} m, bottom wraps {self.bottom_wraps}, "
                     f"top wraps {self.top_wraps}, carriage passes {self.carriage_passes}, "
                     f"revolutions {self.revolutions}")
        return "\n".join(lines)

    def to_json(self) -> dict[str, Any]:
        return {
            "web_width_m": self.web_width_m,
            "rows": [asdict(r) for r in self.rows],
            "bottom_wraps": self.bottom_wraps,
            "top_wraps": self.top_wraps,
            "carriage_passes": self.carriage_passes,
            "revolutions": self.revolutions,
        }


@dataclass(frozen=True)
class WrapFormat:
    material: Material
    web_width_m: float
    bands: tuple[Band, ...]  # in file order, so band[i] in messages is the i-th [[band]]
    material_key: str = "custom"  # "kraft" | "lldpe" | "custom": what the file said

    # --- reading and writing -----------------------------------------------------------------

    @classmethod
    def from_toml(cls, path: str | Path, load_height_m: float | None = None) -> WrapFormat:
        return cls.from_dict(read_toml(path), str(path), load_height_m)

    @classmethod
    def from_dict(
        cls, data: dict[str, Any], source: str = "wrap", load_height_m: float | None = None
    ) -> WrapFormat:
        """Validate a parsed WRAP.toml. Bands are named ``band[i]`` in errors, i counting the
        ``[[band]]`` tables from 0 in file order. With `load_height_m`, also `check_fits`."""
        top = Table(data, source)
        if isinstance(data.get("material"), dict):
            key, material = "custom", _custom_material(top.table("material"))
        else:
            key = top.choice("material", (*MATERIALS, "custom"))
            if key == "custom":
                raise top.error("material", "a custom material is written as a [material] table"
                                " of its values, in place of material = \"custom\"")
            material = MATERIALS[key]
        web = top.number("web_width_m", positive=True, maximum=MAX_WEB_WIDTH_M)
        raw = top.array("band")
        if not raw:
            raise top.error("band", "must list at least one [[band]]")
        bands = tuple(
            _band(Table(item, source, f"band[{i}]"), material, web) for i, item in enumerate(raw)
        )
        top.done()
        wrap = cls(material, web, bands, key)
        if load_height_m is not None:
            wrap.check_fits(load_height_m, source)
        return wrap

    def check_fits(self, load_height_m: float, source: str) -> None:
        """Reject bands reaching above the load: there is nothing there to hold the web."""
        for i, band in enumerate(self.bands):
            if band.to_m > load_height_m + FIT_TOLERANCE_M:
                raise InputError(source, f"band[{i}].to_m", f"{band.to_m} m is above the top of"
                                 f" the load ({load_height_m:.3f} m)")

    def to_dict(self) -> dict[str, Any]:
        """The WRAP.toml content. A material that is not its named card (e.g. `scaled`) is
        written out as a custom [material] table, so the file says what was simulated."""
        named = MATERIALS.get(self.material_key) == self.material
        return {
            "material": self.material_key if named else asdict(self.material),
            "web_width_m": self.web_width_m,
            "band": [asdict(b) for b in self.bands],
        }

    def to_toml(self) -> str:
        data = self.to_dict()
        lines = ["# Wrap format (WRAP.toml); heights in metres from the sled surface."]
        if isinstance(data["material"], str):
            lines.append(f"material = {_toml_value(data['material'])}")
        lines.append(f"web_width_m = {_toml_value(data['web_width_m'])}")
        if isinstance(data["material"], dict):
            lines.append("\n[material]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in data["material"].items()]
        for band in data["band"]:
            lines.append("\n[[band]]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in band.items()]
        return "\n".join(lines) + "\n"

    # --- variants ------------------------------------------------------------------------------

    def scaled(self, stiffness_scale: float = 1.0, tension_scale: float = 1.0) -> WrapFormat:
        """The format as a calibration corrects it: stiffer or softer web, other tensions."""
        material = replace(
            self.material, stiffness_n_per_m=self.material.stiffness_n_per_m * stiffness_scale)
        bands = tuple(replace(b, tension_n=b.tension_n * tension_scale) for b in self.bands)
        return replace(self, material=material, bands=bands)

    def with_bands(self, bands: Iterable[Band]) -> WrapFormat:
        return replace(self, bands=tuple(bands))

    # --- what the membrane sees ----------------------------------------------------------------

    def layers_over(self, z0: float, z1: float) -> float:
        """Average number of web layers over [z0, z1]; overlapping bands add up."""
        return sum(b.layers * b.overlap_m(z0, z1) for b in self.bands) / _span(z0, z1)

    def line_tension_n_per_m(self, z0: float, z1: float) -> float:
        """Average hoop pretension over [z0, z1], newtons per metre of height."""
        total = sum(b.layers * b.tension_n * b.overlap_m(z0, z1) for b in self.bands)
        return total / self.web_width_m / _span(z0, z1)

    def covers(self, z0: float, z1: float) -> bool:
        return any(b.overlap_m(z0, z1) > 0 for b in self.bands)

    # --- what it costs and how a machine applies it ----------------------------------------------

    def material_used(
        self, pallet_top_m: float, pallet_perimeter_m: float, load_perimeter_m: float
    ) -> MaterialUsed:
        """Web area, mass and roll length: each layer goes once round the pallet's perimeter
        below `pallet_top_m` and round the load's above it."""
        area = sum(
            b.layers * (b.overlap_m(0.0, pallet_top_m) * pallet_perimeter_m
                        + b.overlap_m(pallet_top_m, math.inf) * load_perimeter_m)
            for b in self.bands
        )
        return MaterialUsed(area, area * self.material.grammage_kg_m2, area / self.web_width_m)

    def material_used_on(self, layout: Layout) -> MaterialUsed:
        """`material_used` for a laid-out unit: round its pallet, then round its bundles."""
        px, py, pz = layout.pallet_size_m
        lx, ly = layout.outline_m
        return self.material_used(pz, 2 * (px + py), 2 * (lx + ly))

    def machine_recipe(self) -> Recipe:
        """One row per band, lowest first. A band no taller than the web is wrapped with the
        carriage parked at its bottom (`layers` wraps); a taller one with `layers` carriage
        passes, the carriage rising one web width per revolution (no overlap within a pass)."""
        bands = sorted(self.bands, key=lambda b: (b.from_m, b.to_m))
        bottom = 0 if bands[0].from_m <= BOTTOM_ZONE_MAX_M else None
        top = max(range(len(bands)), key=lambda i: (bands[i].to_m, bands[i].from_m))
        rows = []
        for i, b in enumerate(bands):
            zone = "bottom" if i == bottom else "top" if i == top else "middle"
            if b.height_m <= self.web_width_m + _HEIGHT_EPS_M:
                revolutions, passes = b.layers, 0
            else:
                per_pass = math.ceil(b.height_m / self.web_width_m - _HEIGHT_EPS_M)
                revolutions, passes = b.layers * per_pass, b.layers
            rows.append(RecipeRow(zone, b.from_m, b.to_m, b.from_m, revolutions, passes,
                                  b.tension_n))
        return Recipe(self.web_width_m, tuple(rows))


def _span(z0: float, z1: float) -> float:
    if not z1 > z0:
        raise ValueError(f"height interval [{z0}, {z1}] is empty")
    return z1 - z0


def _custom_material(t: Table) -> Material:
    name = t.string("name", "custom")
    grammage = t.number("grammage_kg_m2", positive=True)
    stiffness = t.number("stiffness_n_per_m", positive=True)
    strains = {}
    for key in ("yield_strain", "break_strain"):
        strains[key] = t.number(key, positive=True)
        if strains[key] >= MAX_STRAIN:
            raise t.error(key, f"must be < {MAX_STRAIN} (got {strains[key]})")
    if strains["break_strain"] <= strains["yield_strain"]:
        raise t.error("break_strain", f"must be above yield_strain ({strains['yield_strain']})"
                      f" (got {strains['break_strain']})")
    hardening = t.number("hardening_ratio", 0.1, minimum=0.0)
    cd_ratio = t.number("cd_ratio", 0.5, positive=True, maximum=1.0)
    t.done()
    return Material(name, grammage, stiffness, strains["yield_strain"], strains["break_strain"],
                    hardening, cd_ratio)


def _band(t: Table, material: Material, web_width_m: float) -> Band:
    from_m = t.number("from_m", minimum=0.0)
    to_m = t.number("to_m")
    if to_m <= from_m:
        raise t.error("to_m", f"must be above from_m ({from_m} m) (got {to_m})")
    layers = t.integer("layers", minimum=1)
    tension = t.number("tension_n", positive=True)
    limit = material.break_force_n_per_m * web_width_m
    if tension > limit:
        raise t.error("tension_n", f"{tension} N is above what the material can bear: one layer"
                      f" of a {web_width_m} m web breaks at {limit:.0f} N"
                      f" ({material.break_force_n_per_m:.0f} N/m)")
    t.done()
    return Band(from_m, to_m, layers, tension)


def _toml_value(value: str | float) -> str:
    """A TOML scalar that reads back equal: floats by repr, strings as basic strings."""
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    return repr(value)

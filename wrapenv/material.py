"""Material cards: one layer of web as applied, its law, strength and how it is laid.

Every figure is sourced, derived or marked assumed in docs/materials.md ([S], [D], [A]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from wrapenv.config import Table

#: Strains at or above this are typos (1000 %), not materials.
MAX_STRAIN = 10.0
MATERIAL_KINDS = ("film", "paper")
#: Highest film pre-stretch accepted: 400 %, the top of what powered pre-stretch reaches [S].
MAX_PRESTRETCH = 4.0


@dataclass(frozen=True)
class Relaxation:
    """How a wrap's tension falls while it stands (constant length): a Prony series,
    T(t) / T0 = plateau + sum(a_i exp(-t / tau_i)), with the a_i summing to 1 - plateau."""

    plateau: float = 1.0
    terms: tuple[tuple[float, float], ...] = ()  # (amplitude, time constant in hours)

    def retained(self, hours: float) -> float:
        """Fraction of the wrapping tension left after `hours`."""
        return self.plateau + sum(a * math.exp(-hours / tau) for a, tau in self.terms)


#: LLDPE at 23 °C: 26 % lost in 30 days, most of it in the first 2 h (Dunno & Symanski 2021);
#: the Prony fit to those endpoints is docs/materials.md L5 [A].
FILM_RELAXATION = Relaxation(0.74, ((0.18, 0.5), (0.08, 72.0)))
#: Kraft paper: no published relaxation of wrapped paper was found; paper relaxes by a fifth to
#: a quarter at constant strain (docs/materials.md, P5) [A].
PAPER_RELAXATION = Relaxation(0.80, ((0.10, 1.0), (0.10, 100.0)))
NO_RELAXATION = Relaxation()


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
    #: "film" (clings, can be roped and pre-stretched) or "paper" (neither).
    kind: str = "film"
    #: The pre-stretch (fraction: 2.5 = 250 %) the card's applied figures are for; None: the web
    #: is not pre-stretched.
    prestretch: float | None = None
    #: How its wrapping tension relaxes while the wrapped load stands.
    relaxation: Relaxation = NO_RELAXATION

    @property
    def yield_force_n_per_m(self) -> float:
        return self.stiffness_n_per_m * self.yield_strain

    @property
    def break_force_n_per_m(self) -> float:
        hardening = self.hardening_ratio * self.stiffness_n_per_m
        return self.yield_force_n_per_m + hardening * (self.break_strain - self.yield_strain)

    def grammage_at(self, prestretch: float | None) -> float:
        """Mass per m² of film laid at another pre-stretch: thickness falls as (1 + p)^-0.5
        (docs/materials.md, L2) [D]; paper and the card's own pre-stretch: the card's value."""
        if prestretch is None or self.prestretch is None:
            return self.grammage_kg_m2
        return self.grammage_kg_m2 * ((1 + self.prestretch) / (1 + prestretch)) ** 0.5


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
        kind="paper",
        relaxation=PAPER_RELAXATION,  # [A] P5
    ),
    "lldpe": Material(  # card 2b, cast film as applied after 250 % pre-stretch
        name="LLDPE cast stretch film (applied)",
        grammage_kg_m2=0.0098,  # [D] 920 kg/m³ x 10.7 µm (t = 20 µm / √3.5)
        stiffness_n_per_m=2500.0,  # [D]/[A] L2: 240 MPa x 10.7 µm
        yield_strain=0.15,  # [D]/[A] L3: re-yield at the pre-stretch flow stress
        break_strain=0.55,  # [D] (1 + 4.5) / 3.5 - 1, rounded down
        hardening_ratio=0.925,  # [D] strength 1300 N/m: (1300 - 375) / (2500 x 0.4)
        cd_ratio=0.5,  # [A] no public figure
        kind="film",
        prestretch=2.5,  # [S] powered pre-stretch of 200-300 % typical
        relaxation=FILM_RELAXATION,  # [S]/[A] L5
    ),
}
#: Web tension per layer for a 0.5 m web, newtons: [A] P4 (paper), [S] L4 (film).
DEFAULT_TENSION_N: dict[str, float] = {"kraft": 250.0, "lldpe": 70.0}


def custom_material(t: Table) -> Material:
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
    kind = t.choice("kind", MATERIAL_KINDS, "film")
    relaxation = _relaxation(t.table("relaxation")) if t.has("relaxation") else NO_RELAXATION
    prestretch = (t.number("prestretch", minimum=0.0, maximum=MAX_PRESTRETCH)
                  if t.has("prestretch") else None)
    if prestretch is not None and kind == "paper":
        raise t.error("prestretch", "paper is not pre-stretched")
    t.done()
    return Material(name, grammage, stiffness, strains["yield_strain"], strains["break_strain"],
                    hardening, cd_ratio, kind, prestretch, relaxation)


def _relaxation(t: Table) -> Relaxation:
    """A custom card's `relaxation = {plateau = ..., terms = [[amplitude, tau_h], ...]}`."""
    plateau = t.number("plateau", positive=True, maximum=1.0)
    terms = []
    for i, term in enumerate(t.array("terms") if t.has("terms") else []):
        if (not isinstance(term, list) or len(term) != 2
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in term)
                or not (term[0] >= 0 and term[1] > 0 and math.isfinite(term[1]))):
            raise t.error(f"terms[{i}]", f"must be [amplitude >= 0, time constant in hours > 0] "
                                         f"(got {term!r})")
        terms.append((float(term[0]), float(term[1])))
    if not math.isclose(plateau + sum(a for a, _ in terms), 1.0, abs_tol=1e-6):
        raise t.error("terms", f"amplitudes must add up to 1 - plateau ({1 - plateau:g})")
    t.done()
    return Relaxation(plateau, tuple(terms))


def tension_limit_n(material: Material, web_width_m: float) -> float:
    """The highest web tension a file may ask: one layer's breaking force."""
    return material.break_force_n_per_m * web_width_m


def check_tension(t: Table, key: str, material: Material, web_width_m: float) -> float:
    """A web tension: > 0 and no more than what one layer of the web bears."""
    tension = t.number(key, positive=True)
    limit = tension_limit_n(material, web_width_m)
    if tension > limit:
        raise t.error(key, f"{tension} N is above what the material can bear: one layer"
                      f" of a {web_width_m} m web breaks at {limit:.0f} N"
                      f" ({material.break_force_n_per_m:.0f} N/m)")
    return tension



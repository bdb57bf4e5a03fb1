"""Material cards: one layer of web as applied, its law, strength and how it is laid.

Every figure is sourced, derived or marked assumed in docs/materials.md ([S], [D], [A]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from wrapenv.config import (
    MAX_FRICTION_COEFFICIENT,
    InputError,
    Table,
    is_finite_number,
    is_real_number,
)

#: Strains at or above this are typos (1000 %), not materials.
MAX_STRAIN = 10.0
#: A custom card's bounds [A] (docs/materials.md, "A custom card's bounds"), each past any web
#: and short of the unit slip it catches: a grammage of 1 kg/m² is board (90 typed for
#: 90 g/m²); a stiffness of 1e8 N/m is a steel strap's (3e9 typed, a modulus in Pa, for the
#: modulus times the thickness); no web yields past 50 % and no paper stretches past 30 %
#: before it breaks (0.8 typed for 0.8 %, 7 for 7 %).
MAX_GRAMMAGE_KG_M2 = 1.0
MAX_STIFFNESS_N_PER_M = 1e8
MAX_YIELD_STRAIN = 0.5
MAX_PAPER_BREAK_STRAIN = 0.3
MATERIAL_KINDS = ("film", "paper")
#: Highest film pre-stretch accepted: 400 %, the top of what powered pre-stretch reaches [S].
MAX_PRESTRETCH = 4.0
#: Density of the web as applied, for a thickness the card does not give: paper 700 kg/m³
#: [A] (480-860 [S], docs/materials.md section 1), LLDPE 920 kg/m³ [S].
DENSITY_KG_M3 = {"paper": 700.0, "film": 920.0}
#: Paper on paper, static (docs/materials.md, P6) [A].
PAPER_INTERLAYER_FRICTION = 0.4
#: A glued paper tail holds this fraction of the paper's breaking force (P5) [A].
GLUED_SEAM_FRACTION = 0.5
#: A panel's shear stiffness over the web's: a wrinkled membrane takes shear only through
#: tension strips at 45 degrees, which carry a quarter of its stiffness in shear [A].
SHEAR_RATIO = 0.25
#: Damping of each wrap element, a fraction of critical for its stiffness and the masses it
#: joins [A]: it shapes the elastic peak.
DAMPING_RATIO = 0.2


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
#: Kraft paper: no published relaxation of wrapped paper was found; paper is viscoelastic and
#: relaxes at constant strain, assumed like film: 20 % in 30 days (docs/materials.md, P8) [A].
PAPER_RELAXATION = Relaxation(0.80, ((0.10, 1.0), (0.10, 100.0)))
NO_RELAXATION = Relaxation()
#: The law a custom card of each kind takes when it gives none.
KIND_RELAXATION: dict[str, Relaxation] = {"paper": PAPER_RELAXATION, "film": FILM_RELAXATION}


@dataclass(frozen=True)
class Look:
    """How a web is drawn over the bench's frames (docs/materials.md, "The cards' look")."""

    fill_rgb: tuple[int, int, int]
    line_rgb: tuple[int, int, int]
    #: Opacity a synthetic recording draws the web with: paper hides the labels under it,
    #: film shows them (reports draw every web at `wrapenv.render.WRAP_ALPHA`).
    recorded_alpha: float


#: The look of each kind of web: kraft paper light brown and nearly opaque, film light
#: blue-grey and see-through.
LOOKS = {"paper": Look((205, 160, 105), (110, 75, 40), 0.9),
         "film": Look((200, 214, 228), (85, 105, 130), 0.3)}


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
    #: One layer's thickness as applied (bending strain round a load's edge); None: grammage
    #: over the kind's density (`layer_thickness_m`).
    thickness_m: float | None = None
    #: Static friction of one layer on the next; None: the layers cling (film) or, for paper,
    #: `PAPER_INTERLAYER_FRICTION` (`interlayer_mu`).
    interlayer_friction: float | None = None
    #: Force per metre of height the wrap's tail joint (glue, clamp, cling) holds before it
    #: lets go; None: `seam_holds_n_per_m` (a fraction of the web's own breaking force).
    seam_strength_n_per_m: float | None = None
    #: The membrane model's two figures no source gives (`SHEAR_RATIO`, `DAMPING_RATIO`),
    #: here so that a card or a sensitivity study can set them as it sets `cd_ratio`.
    shear_ratio: float = SHEAR_RATIO
    damping_ratio: float = DAMPING_RATIO

    @property
    def yield_force_n_per_m(self) -> float:
        return self.stiffness_n_per_m * self.yield_strain

    @property
    def break_force_n_per_m(self) -> float:
        hardening = self.hardening_ratio * self.stiffness_n_per_m
        return self.yield_force_n_per_m + hardening * (self.break_strain - self.yield_strain)

    @property
    def layer_thickness_m(self) -> float:
        """Metres; from the grammage and the kind's density when the card gives none [D]."""
        if self.thickness_m is not None:
            return self.thickness_m
        return self.grammage_kg_m2 / DENSITY_KG_M3[self.kind]

    @property
    def look(self) -> Look:
        """How the web is drawn: its kind's look, so a custom card gets it from its `kind`."""
        return LOOKS[self.kind]

    @property
    def clings(self) -> bool:
        """Whether stacked layers stick together: film without a friction figure."""
        return self.kind == "film" and self.interlayer_friction is None

    @property
    def interlayer_mu(self) -> float:
        """Friction of a layer on the next (only meaningful when the layers do not cling)."""
        if self.interlayer_friction is not None:
            return self.interlayer_friction
        return PAPER_INTERLAYER_FRICTION

    @property
    def seam_holds_n_per_m(self) -> float:
        """N/m of height the tail joint holds: the card's, else film's cling lap holds as
        much as the film (it does not slip before the film tears) and a glued paper tail
        `GLUED_SEAM_FRACTION` of the paper's breaking force [A] (docs/materials.md, P5)."""
        if self.seam_strength_n_per_m is not None:
            return self.seam_strength_n_per_m
        fraction = 1.0 if self.kind == "film" else GLUED_SEAM_FRACTION
        return fraction * self.break_force_n_per_m

    def grammage_at(self, prestretch: float | None) -> float:
        """Mass per m² of film laid at another pre-stretch. Every revolution lays the full web
        width, so the film stretched (1 + p) times in length thins as much: the web laid
        weighs what came off the roll (docs/materials.md, L2) [D]; paper and the card's own
        pre-stretch: the card's value."""
        if prestretch is None or self.prestretch is None:
            return self.grammage_kg_m2
        return self.grammage_kg_m2 * (1 + self.prestretch) / (1 + prestretch)


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
        relaxation=PAPER_RELAXATION,  # [A] P8
        thickness_m=1.3e-4,  # [A] 90 g/m² at ≈ 700 kg/m³
        interlayer_friction=PAPER_INTERLAYER_FRICTION,  # [A] P6: paper slides on paper
        seam_strength_n_per_m=3000.0,  # [A] P5: glued tail, half the web's strength
    ),
    "lldpe": Material(  # card 2b, cast film as applied after 250 % pre-stretch
        name="LLDPE cast stretch film (applied)",
        grammage_kg_m2=0.0184 / 3.5,  # [D] the roll's 18.4 g/m² (920 kg/m³ x 20 µm) / 3.5
        stiffness_n_per_m=2500.0,  # [A] L2: oriented film, ≈ 440 MPa x 5.7 µm
        yield_strain=0.15,  # [D]/[A] L3: re-yield at the pre-stretch flow stress
        break_strain=0.55,  # [D] (1 + 4.5) / 3.5 - 1, rounded down
        hardening_ratio=0.925,  # [D] strength 1300 N/m: (1300 - 375) / (2500 x 0.4)
        cd_ratio=0.5,  # [A] no public figure
        kind="film",
        prestretch=2.5,  # [S] powered pre-stretch of 200-300 % typical
        relaxation=FILM_RELAXATION,  # [S]/[A] L5
        thickness_m=20e-6 / 3.5,  # [D] L2: 20 µm stretched 3.5 x at the web's full width
        # layers cling (interlayer_friction None) and the clung tail holds as the film (P5)
    ),
}


def custom_material(t: Table) -> Material:
    name = t.string("name", "custom")
    kind = t.choice("kind", MATERIAL_KINDS, "film")
    grammage = t.number("grammage_kg_m2", positive=True, maximum=MAX_GRAMMAGE_KG_M2,
                        hint=_grams_hint(t))
    stiffness = t.number("stiffness_n_per_m", positive=True, maximum=MAX_STIFFNESS_N_PER_M,
                         hint="stiffer than a steel strap: a modulus in Pa? The card wants the "
                              "modulus times the web's thickness (3 GPa x 130 µm = 4e5 N/m)")
    top_break = MAX_PAPER_BREAK_STRAIN if kind == "paper" else None
    strains = {key: t.number(key, positive=True, maximum=top, hint=_percent_hint(t, key))
               for key, top in (("yield_strain", MAX_YIELD_STRAIN), ("break_strain", top_break))}
    if strains["break_strain"] >= MAX_STRAIN:
        raise t.error("break_strain", f"must be < {MAX_STRAIN} (got {strains['break_strain']})")
    if strains["break_strain"] <= strains["yield_strain"]:
        raise t.error("break_strain", f"must be above yield_strain ({strains['yield_strain']})"
                      f" (got {strains['break_strain']})")
    hardening = t.number("hardening_ratio", 0.1, minimum=0.0)
    if hardening >= 1.0:   # hardening as stiff as the elastic slope: the web never yields
        raise t.error("hardening_ratio", f"must be < 1, a slope below the elastic one "
                      f"(got {hardening})")
    cd_ratio = t.number("cd_ratio", 0.5, positive=True, maximum=1.0)
    # no law given: the kind's card's (a custom paper relaxes as paper is assumed to, P8)
    relaxation = (_relaxation(t.table("relaxation")) if t.has("relaxation")
                  else KIND_RELAXATION[kind])
    prestretch = (t.number("prestretch", minimum=0.0, maximum=MAX_PRESTRETCH)
                  if t.has("prestretch") else None)
    if prestretch is not None and kind == "paper":
        raise t.error("prestretch", "paper is not pre-stretched")
    material = Material(name, grammage, stiffness, strains["yield_strain"],
                        strains["break_strain"], hardening, cd_ratio, kind, prestretch,
                        relaxation, **_failure_fields(t))
    t.done()
    return material


def _grams_hint(t: Table) -> str:
    value = t.data.get("grammage_kg_m2")
    return (f"grams per m²? The card wants kilograms ({value:g} g/m² is {value / 1000:g} kg/m²)"
            if isinstance(value, int | float) and 1 <= value <= 1000 else "")


def _percent_hint(t: Table, key: str) -> str:
    value = t.data.get(key)
    return (f"a percentage? Strains are fractions ({value:g} % is {value / 100:g})"
            if isinstance(value, int | float) and value >= 0.3 else "")


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


#: A web thicker than this is a board, not a wrap.
MAX_THICKNESS_M = 0.005


def _failure_fields(t: Table) -> dict[str, float]:
    """The optional keys of how a web fails beyond its own law: thickness (bending round an
    edge), layer-on-layer friction and the tail's strength; absent keys keep the documented
    defaults (`Material.layer_thickness_m`, `interlayer_mu`, `seam_holds_n_per_m`). And the
    membrane model's shear and damping ratios, at most 1 (as stiff in shear as in tension;
    critical damping)."""
    limits = {"thickness_m": MAX_THICKNESS_M, "interlayer_friction": MAX_FRICTION_COEFFICIENT,
              "seam_strength_n_per_m": None, "shear_ratio": 1.0, "damping_ratio": 1.0}
    return {key: t.number(key, positive=True, maximum=top)
            for key, top in limits.items() if t.has(key)}


def tension_limit_n(material: Material, web_width_m: float) -> float:
    """The highest web tension a file may ask: one layer's breaking force."""
    return material.break_force_n_per_m * web_width_m


#: The longest a wrapped load is taken to stand before the road: a year. Longer is a unit
#: mistaken (seconds, or minutes, for hours); the relaxation laws have long levelled off.
MAX_HOURS_SINCE_WRAPPING = 8760.0


def check_hours_since_wrapping(hours: float) -> float:
    """How long a wrap stood before its test: 0 to a year."""
    if not (is_finite_number(hours) and 0 <= hours <= MAX_HOURS_SINCE_WRAPPING):
        number = is_real_number(hours)
        late = number and hours > MAX_HOURS_SINCE_WRAPPING
        unit = ": hours, not seconds or minutes" if late else ""
        raise InputError("wrap", "hours_since_wrapping", f"must be from 0 to "
                         f"{MAX_HOURS_SINCE_WRAPPING:g} h, a year (got "
                         f"{f'{hours:g}' if number else repr(hours)}{unit})")
    return float(hours)


def check_tension(t: Table, key: str, material: Material, web_width_m: float) -> float:
    """A web tension: > 0 and no more than what one layer of the web bears."""
    tension = t.number(key, positive=True)
    limit = tension_limit_n(material, web_width_m)
    if tension > limit:
        raise t.error(key, f"{tension} N is above what the material can bear: one layer"
                      f" of a {web_width_m} m web breaks at {limit:.0f} N"
                      f" ({material.break_force_n_per_m:.0f} N/m)")
    return tension



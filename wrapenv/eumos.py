"""EUMOS 40509 acceptance criteria and the verdict of a bench run.

Per test level (paper, section 2): (i) permanent displacement of every part <= 5 % of the load
height; (ii) permanent displacement in the lowest 20 cm < 4 cm relative to the pallet;
(iii) elastic displacement during the test <= 10 % of the load height; (iv) no structural damage:
here no bundle fallen or toppled (and, with a wrap, no torn wrap and no seam that let go).
Each figure criterion is one row of `EUMOS_CRITERIA`, which the verdict, the margin, the printed
table and the reports read.

Permanent means since the unit was first put on the sled. A lab runs one unit through the
levels, and the published summaries define the permanent deformation as what is left of the
load unit after the test, against the unit before it: the source paper (section 2: "the residual
deformations of the load unit after the test ended") and the Wikipedia summary of EUMOS 40509
("Acceleration test": the certificate shows "a picture of the pallet load before and after the
test", https://en.wikipedia.org/wiki/Acceleration_test). So criteria (i) and (ii), and the
optional shift between layers, read the displacement since the unit was put on the sled
(`permanent_total_max_m`), which for a fresh unit per level is the level's own
(`permanent_max_m`). Elastic displacement is what a pulse does while it acts: measured from where
the unit stood when that level began.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from wrapenv.config import InputError, is_finite_number
from wrapenv.trace import Trace
from wrapenv.wrap_report import WrapReport

LOW_ZONE_HEIGHT_M = 0.20
#: A bundle left leaning by more than this is toppled: boxes stacked flat never rest tilted.
TOPPLE_ANGLE_RAD = math.radians(10.0)
#: An upright bundle this much lower than it was stacked has left its support (`fallen`).
#: Upright bundles on their support, squeezed by a wrap or not, sank 0.46 mm at most in every
#: passing level of the examples' EUMOS sequences to 0.8 g, both orientations (2026-11-25);
#: tests/wrapenv/test_bench_decided.py holds a squeezed stack's to a tenth of this.
FALL_DROP_M = 0.03
#: The damage entry of a wrap element that reached its breaking force.
WRAP_TORN = "wrap_torn"
#: The damage entry of a wrap whose tail seam let go: the rings it closed went slack.
WRAP_OPENED = "wrap_opened"
#: The criterion of damage (it reads no figure: any damage fails it).
NO_DAMAGE = "no_damage"


@dataclass(frozen=True)
class Criterion:
    """One figure criterion: `figure` (a `LevelVerdict` field, in metres) must stay within
    `limit`, a fraction of the load height (`of_height`) or metres; `strict`: below it (<),
    else at most it (<=)."""

    key: str        # as in the verdict's `criteria`
    label: str      # for tables and reports
    figure: str
    limit: float
    of_height: bool
    strict: bool
    note: str = ""  # what a reader needs besides the limit

    def limit_m(self, load_height_m: float) -> float:
        return self.limit * load_height_m if self.of_height else self.limit

    def holds(self, figure_m: float, load_height_m: float) -> bool:
        limit = self.limit_m(load_height_m)
        return bool(figure_m < limit if self.strict else figure_m <= limit)

    def value(self, level: LevelVerdict) -> float | None:
        return getattr(level, self.figure)

    def describe(self, load_height_m: float, at_most: str = "<=") -> str:
        """The limit as a reader wants it: "<= 40.2 mm (5 % of height)" (`at_most`: the sign
        of <=, "≤" on a page)."""
        sign = "<" if self.strict else at_most
        if self.of_height:
            return (f"{sign} {1000 * self.limit_m(load_height_m):.1f} mm "
                    f"({100 * self.limit:g} % of height)")
        return f"{sign} {1000 * self.limit:.0f} mm" + (f" ({self.note})" if self.note else "")

    def figure_text(self, level: LevelVerdict, load_height_m: float) -> str:
        """The level's figure in mm, and in % of the load height if the limit is."""
        value = self.value(level)
        if value is None:
            return "n/a"
        pct = f" ({100 * value / load_height_m:.1f} %)" if self.of_height else ""
        return f"{1000 * value:.1f} mm{pct}"


ELASTIC = Criterion("elastic_10pct", "Elastic max", "elastic_max_m", 0.10, True, False)
PERMANENT = Criterion("permanent_5pct", "Permanent max", "permanent_total_max_m", 0.05, True,
                      False)
LOW_ZONE = Criterion("low20_4cm", f"Lowest {100 * LOW_ZONE_HEIGHT_M:.0f} cm, permanent",
                     "permanent_low20_m", 0.04, False, True,
                     f"bundles below {100 * LOW_ZONE_HEIGHT_M:.0f} cm")
#: EUMOS 40509's figure criteria, in the order tables show them.
EUMOS_CRITERIA = (ELASTIC, PERMANENT, LOW_ZONE)
#: The key of the optional limit on the shift between layers (`Limits.layer_shift_fraction`).
LAYER_SHIFT = "layer_shift"


def layer_shift_criterion(fraction: float) -> Criterion:
    """A limit on the permanent shift of a layer on the one below, as a fraction of the load
    height: not in EUMOS 40509 itself; secondary summaries and vendors quote 2 %."""
    return Criterion(LAYER_SHIFT, "Layer shift", "layer_shift_max_m", fraction, True, False)


@dataclass(frozen=True)
class Limits:
    """Which criteria judge a level: EUMOS 40509's, and optionally a limit on the permanent
    shift of a layer on the one below (a fraction of the load height; None: not judged)."""

    layer_shift_fraction: float | None = None

    def __post_init__(self) -> None:
        f = self.layer_shift_fraction
        if f is not None and not (is_finite_number(f) and 0 < f <= 1):
            raise InputError("criteria", "layer_shift_fraction",
                             f"must be in (0, 1] of the load height (got {f})")

    def criteria(self) -> tuple[Criterion, ...]:
        if self.layer_shift_fraction is None:
            return EUMOS_CRITERIA
        return (*EUMOS_CRITERIA, layer_shift_criterion(self.layer_shift_fraction))


#: EUMOS 40509's criteria alone.
EUMOS_LIMITS = Limits()


@dataclass(frozen=True)
class BodyResult:
    name: str
    permanent_m: float | None
    elastic_max_m: float | None


@dataclass(frozen=True)
class LevelVerdict:
    """One level judged (`evaluate`): each criterion's figure and pass or fail, damage, and why
    a run was invalid or ended early; its fields are `simulate`'s JSON keys per level."""

    level_g: float
    passed: bool
    valid: bool
    elastic_max_m: float | None
    elastic_max_pct: float | None
    permanent_max_m: float | None
    permanent_max_pct: float | None
    permanent_low20_m: float | None
    pallet_slip_m: float | None
    damage: tuple[str, ...]
    criteria: dict[str, bool]
    bodies: tuple[BodyResult, ...]
    invalid_reason: str = ""
    wrap: WrapReport | None = None
    #: Why the level was stopped before rest, already failed (`SimSettings.stop_when_decided`,
    #: or, in every mode, a body gone over the edge of the sled's deck); its figures are then
    #: those at the stop.
    stopped_early: str = ""
    #: Why the level ended with a body still moving (`Trace.not_at_rest`): its permanent
    #: figures are those at the end, which may not be where the unit would rest.
    not_at_rest: str = ""
    #: Permanent displacement since the unit was first put on the sled (the criteria's figure;
    #: `permanent_max_m` is this level's own). None: not measured (the level's own is used).
    permanent_total_max_m: float | None = None
    permanent_total_max_pct: float | None = None
    #: The largest permanent shift of a layer on the one below, since the unit was put on.
    layer_shift_max_m: float | None = None
    layer_shift_max_pct: float | None = None
    #: The criteria that judged the level (not part of the JSON: `criteria` names them).
    limits: Limits = EUMOS_LIMITS

    def __post_init__(self) -> None:
        if self.permanent_total_max_m is None:
            object.__setattr__(self, "permanent_total_max_m", self.permanent_max_m)
            object.__setattr__(self, "permanent_total_max_pct", self.permanent_max_pct)

    def to_json(self) -> dict:
        out = asdict(self)
        del out["limits"]
        out["damage"] = list(self.damage)
        out["bodies"] = [asdict(b) for b in self.bodies]
        if self.valid:
            del out["invalid_reason"]
        if not self.stopped_early:
            del out["stopped_early"]
        if not self.not_at_rest:
            del out["not_at_rest"]
        if self.wrap is None:
            del out["wrap"]
        else:
            out["wrap"] = self.wrap.to_json()
        return out


@dataclass(frozen=True)
class Verdict:
    """A test sequence judged, level by level. It passes only if every level does and every run
    stayed physical: a simulation that blew up is never a pass."""

    load_height_m: float
    levels: tuple[LevelVerdict, ...] = field(default_factory=tuple)
    #: "cumulative": one unit through the levels, as a lab runs it; "fresh": a new unit each.
    sequence: str = "cumulative"

    @property
    def valid(self) -> bool:
        return all(level.valid for level in self.levels)

    @property
    def passed(self) -> bool:
        return bool(self.levels) and all(level.passed for level in self.levels)

    @property
    def margin(self) -> float:
        """How far inside the criteria the worst level stayed (see `level_margin`)."""
        return min((level_margin(v, self.load_height_m) for v in self.levels), default=-1.0)

    def criteria(self) -> tuple[Criterion, ...]:
        """The figure criteria that judged the run (every level is judged by the same), in
        the order tables show them; EUMOS 40509's for a run of no level."""
        return self.levels[0].limits.criteria() if self.levels else EUMOS_CRITERIA

    def reported_passed(self, level: LevelVerdict) -> bool:
        """Whether `level` is reported as passed: no level of a run that became unphysical is
        (CONTRACTS.md), though one before the blow-up met its criteria."""
        return self.valid and level.passed

    @property
    def highest_passed_g(self) -> float | None:
        passed = [level.level_g for level in self.levels if self.reported_passed(level)]
        return max(passed) if passed else None

    def to_json(self) -> dict:
        levels = [level.to_json() | {"passed": self.reported_passed(level)}
                  for level in self.levels]
        return {
            "sequence": self.sequence,
            "valid": self.valid,
            "load_height_m": round(self.load_height_m, 6),
            "levels": levels,
            "highest_passed_g": self.highest_passed_g,
        }


def level_margin(level: LevelVerdict, load_height_m: float) -> float:
    """The smallest of 1 - figure/limit over the figure criteria that judged the level: 0 on
    a limit, 0.5 at half of it, < 0 beyond. Damage or an invalid run is -1 at best."""
    criteria = level.limits.criteria()
    ratios = [f / c.limit_m(load_height_m) for c in criteria if (f := c.value(level)) is not None]
    if not level.valid or len(ratios) < len(criteria):
        return -1.0
    margin = 1.0 - max(ratios)
    return min(margin, -1.0) if level.damage else margin


def evaluate(trace: Trace, limits: Limits = EUMOS_LIMITS) -> LevelVerdict:
    """Judge one level from its trace against `limits`; damage is the bodies' (`_damage`) and
    the wrap's, torn or opened, as the trace records it."""
    h = trace.load_height_m
    disp = trace.bundle_displacement_m()
    permanent, elastic = disp[-1], disp.max(axis=0)
    total = trace.permanent_total_m()
    low = trace.bottom_z_m < LOW_ZONE_HEIGHT_M
    low20 = float(total[low].max()) if np.any(low) else 0.0
    shift = trace.layer_shift_m()
    damage = _damage(trace)
    if trace.wrap is not None and trace.wrap.torn:
        damage += (WRAP_TORN,)
    if trace.wrap is not None and trace.wrap.opened:
        damage += (WRAP_OPENED,)
    level = LevelVerdict(
        level_g=round(trace.level_g, 4),
        passed=False,
        valid=trace.valid,
        elastic_max_m=_r(elastic.max()),
        elastic_max_pct=_r(100 * elastic.max() / h, 3),
        permanent_max_m=_r(permanent.max()),
        permanent_max_pct=_r(100 * permanent.max() / h, 3),
        permanent_low20_m=_r(low20),
        pallet_slip_m=_r(trace.pallet_slip_m()),
        damage=damage,
        criteria={},
        bodies=tuple(
            BodyResult(n, _r(p), _r(e)) for n, p, e in zip(trace.names, permanent, elastic,
                                                          strict=True)
        ),
        invalid_reason=trace.invalid_reason,
        wrap=trace.wrap,
        stopped_early=trace.stopped_early,
        not_at_rest=trace.not_at_rest,
        permanent_total_max_m=_r(total.max()),
        permanent_total_max_pct=_r(100 * total.max() / h, 3),
        layer_shift_max_m=_r(shift),
        layer_shift_max_pct=_r(100 * shift / h, 3),
        limits=limits,
    )
    return _judged(level, h)


def _judged(level: LevelVerdict, load_height_m: float) -> LevelVerdict:
    """The level with each criterion's result (a figure that is not finite fails) and the
    verdict: passed only if the run stayed valid and every criterion holds."""
    criteria = {}
    for c in level.limits.criteria():
        figure = c.value(level)
        criteria[c.key] = figure is not None and c.holds(figure, load_height_m)
    criteria[NO_DAMAGE] = not level.damage
    return replace(level, criteria=criteria, passed=level.valid and all(criteria.values()))


def fallen(bundle_z_m: np.ndarray, bottom_z_m: np.ndarray, dropped_m: np.ndarray,
           tilt_rad: np.ndarray) -> np.ndarray:
    """Which bundles have fallen, i.e. left their support: the centre dropped by half the
    bundle's height, below where its underside stood, which a box still on its support cannot
    do by tilting (tipping a 0.33 m bundle onto its 0.19 m side lowers it 7 cm, not 16.5); or,
    standing upright (within `TOPPLE_ANGLE_RAD`), `dropped_m` more than `FALL_DROP_M` below
    where it was stacked: an upright box on its support stands no lower than it was stacked but
    for the solver's millimetres of overlap, so it slid off onto something lower (a bottom
    bundle taller than the pallet off the pallet onto the sled's deck)."""
    upright = tilt_rad <= TOPPLE_ANGLE_RAD
    return (bundle_z_m < bottom_z_m) | (upright & (dropped_m > FALL_DROP_M))


def _damage(trace: Trace) -> tuple[str, ...]:
    tilt = trace.tilt_rad()
    fell = fallen(trace.bundle_pos_m[-1, :, 2], trace.bottom_z_m, trace.dropped_m(), tilt)
    toppled = tilt > TOPPLE_ANGLE_RAD
    out = []
    for name, f, t in zip(trace.names, fell, toppled, strict=True):
        if f:
            out.append(f"{name} fallen")
        elif t:
            out.append(f"{name} toppled")
    return tuple(out)


def _r(x: float, digits: int = 6) -> float | None:
    """Round for reporting; a non-finite figure (a blown-up run) is reported as null."""
    x = float(x)
    return round(x, digits) if math.isfinite(x) else None

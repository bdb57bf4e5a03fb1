"""EUMOS 40509 acceptance criteria and the verdict of a bench run.

Per test level (paper, section 2): (i) permanent displacement of every part <= 5 % of the load
height; (ii) permanent displacement in the lowest 20 cm < 4 cm relative to the pallet;
(iii) elastic displacement during the test <= 10 % of the load height; (iv) no structural damage:
here no bundle fallen or toppled (and, with a wrap, no torn wrap and no seam that let go).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from wrapenv.trace import Trace
from wrapenv.wrap_report import WrapReport

PERMANENT_LIMIT_FRACTION = 0.05
ELASTIC_LIMIT_FRACTION = 0.10
LOW_ZONE_HEIGHT_M = 0.20
LOW_ZONE_LIMIT_M = 0.04
#: A bundle left leaning by more than this is toppled: boxes stacked flat never rest tilted.
TOPPLE_ANGLE_RAD = math.radians(10.0)
#: The damage entry of a wrap element that reached its breaking force.
WRAP_TORN = "wrap_torn"
#: The damage entry of a wrap whose tail seam let go: the rings it closed went slack.
WRAP_OPENED = "wrap_opened"


@dataclass(frozen=True)
class BodyResult:
    name: str
    permanent_m: float | None
    elastic_max_m: float | None


@dataclass(frozen=True)
class LevelVerdict:
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
    #: Why the level was stopped before rest, already failed (`SimSettings.stop_when_decided`);
    #: its figures are then those at the stop.
    stopped_early: str = ""

    def to_json(self) -> dict:
        out = asdict(self)
        out["damage"] = list(self.damage)
        out["bodies"] = [asdict(b) for b in self.bodies]
        if self.valid:
            del out["invalid_reason"]
        if not self.stopped_early:
            del out["stopped_early"]
        if self.wrap is None:
            del out["wrap"]
        else:
            out["wrap"] = self.wrap.to_json()
        return out


@dataclass(frozen=True)
class Verdict:
    load_height_m: float
    levels: tuple[LevelVerdict, ...] = field(default_factory=tuple)

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

    @property
    def highest_passed_g(self) -> float | None:
        passed = [level.level_g for level in self.levels if level.passed]
        return max(passed) if passed else None

    def to_json(self) -> dict:
        return {
            "valid": self.valid,
            "load_height_m": round(self.load_height_m, 6),
            "levels": [level.to_json() for level in self.levels],
            "highest_passed_g": self.highest_passed_g,
        }


def level_margin(level: LevelVerdict, load_height_m: float) -> float:
    """The smallest of 1 - figure/limit over elastic, permanent and lowest-20-cm displacement:
    0 on a limit, 0.5 at half of it, < 0 beyond. Damage or an invalid run is -1 at best."""
    elastic, permanent, low20 = level.elastic_max_m, level.permanent_max_m, level.permanent_low20_m
    if not level.valid or elastic is None or permanent is None or low20 is None:
        return -1.0
    ratios = (elastic / (ELASTIC_LIMIT_FRACTION * load_height_m),
              permanent / (PERMANENT_LIMIT_FRACTION * load_height_m),
              low20 / LOW_ZONE_LIMIT_M)
    margin = 1.0 - max(ratios)
    return min(margin, -1.0) if level.damage else margin


def evaluate(trace: Trace, extra_damage: tuple[str, ...] = ()) -> LevelVerdict:
    """Judge one level from its trace. `extra_damage` adds damage found elsewhere (torn wrap)."""
    h = trace.load_height_m
    disp = trace.bundle_displacement_m()
    permanent, elastic = disp[-1], disp.max(axis=0)
    low = trace.bottom_z_m < LOW_ZONE_HEIGHT_M
    low20 = float(permanent[low].max()) if np.any(low) else 0.0
    damage = _damage(trace) + tuple(extra_damage)
    if trace.wrap is not None and trace.wrap.torn:
        damage += (WRAP_TORN,)
    if trace.wrap is not None and trace.wrap.opened:
        damage += (WRAP_OPENED,)
    criteria = {
        "permanent_5pct": bool(permanent.max() <= PERMANENT_LIMIT_FRACTION * h),
        "low20_4cm": low20 < LOW_ZONE_LIMIT_M,
        "elastic_10pct": bool(elastic.max() <= ELASTIC_LIMIT_FRACTION * h),
        "no_damage": not damage,
    }
    return LevelVerdict(
        level_g=round(trace.level_g, 4),
        passed=trace.valid and all(criteria.values()),
        valid=trace.valid,
        elastic_max_m=_r(elastic.max()),
        elastic_max_pct=_r(100 * elastic.max() / h, 3),
        permanent_max_m=_r(permanent.max()),
        permanent_max_pct=_r(100 * permanent.max() / h, 3),
        permanent_low20_m=_r(low20),
        pallet_slip_m=_r(trace.pallet_slip_m()),
        damage=damage,
        criteria=criteria,
        bodies=tuple(
            BodyResult(n, _r(p), _r(e)) for n, p, e in zip(trace.names, permanent, elastic,
                                                          strict=True)
        ),
        invalid_reason=trace.invalid_reason,
        wrap=trace.wrap,
        stopped_early=trace.stopped_early,
    )


def fallen(bundle_z_m: np.ndarray, bottom_z_m: np.ndarray) -> np.ndarray:
    """Which bundles have fallen: the centre dropped by half the bundle's height, below where
    its underside stood, which a box still on its support cannot do by tilting (tipping a
    0.33 m bundle onto its 0.19 m side lowers it 7 cm, not 16.5); it left its support."""
    return bundle_z_m < bottom_z_m


def _damage(trace: Trace) -> tuple[str, ...]:
    fell = fallen(trace.bundle_pos[-1, :, 2], trace.bottom_z_m)
    toppled = trace.tilt_rad() > TOPPLE_ANGLE_RAD
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

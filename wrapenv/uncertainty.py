"""What the bench does not know, drawn sample by sample, and what a set of samples tells.

A recommendation is robust when it passes in samples of every parameter the model is unsure of:
each friction pair (its calibrated standard deviation, or the CTU Code's quoted ±0.03), the
bundles' mass (±5 %), the web's stiffness and the tension the machine really lays (calibrated,
or assumed ±10 %), the load's give under the web (its bundles' edge stiffness: calibrated, or
assumed ±25 %), and how much of that tension is left when the load travels (its material's
relaxation law, ±5 % of the tension [A]). Every draw is seeded, so the same seed gives the same
sample in any process. It belongs to the bench, not the search: the search verifies its answers
in these samples and the environments can test a program in one (`WrapBenchEnv`'s `uncertain`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from wrapenv.calibrated import Calibration, draw_pair, draw_scale
from wrapenv.load import PAIRS, FrictionPair, LoadUnit
from wrapenv.wrap import WrapFormat

#: Friction standard deviation for a pair without calibration [A]: the CTU Code tabulates one
#: figure per pair, with no spread; ±0.03 is the second decimal its figures are given to.
DEFAULT_FRICTION_STD = 0.03
#: Bundles' mass drawn uniformly within ± this fraction (filling tolerance) [A].
MASS_SPREAD = 0.05
#: Standard deviation of the web's stiffness and of the laid tension without a calibration, as
#: fractions [A]: no supplier card with a stiffness tolerance was found (docs/materials.md, L1),
#: and a wrapper's tension setting is a brake or a dancer, not a measurement.
DEFAULT_SCALE_STD = 0.10
#: Standard deviation of the load's give (its bundles' edge stiffness under the web) without a
#: calibration, as a fraction [A]: docs/materials.md section 5; the design chart
#: (benchmarks/design_chart.py) shows what halving or doubling it does.
DEFAULT_GIVE_STD = 0.25
#: Standard deviation of the tension lost in relaxing, as a fraction of that loss [A] (at 16 h
#: Kraft loses 11 %, so the tension left varies by about ±0.6 %).
RELAXATION_STD = 0.05
#: Hours between wrapping and the road that `recommend` assumes: ASTM D5414 rests a wrapped
#: load 16 h before its impact test, so that the wrap has relaxed as it would in transport.
TRANSPORT_HOURS = 16.0
#: Two-sided 95 % normal quantile, for the Wilson interval of a pass probability.
Z95 = 1.959964


@dataclass(frozen=True)
class Uncertainty:
    """Nominal values and spreads of the sampled parameters."""

    friction_std: dict[str, tuple[float, float]]  # pair -> (static std, kinetic std)
    stiffness_scale: float = 1.0
    stiffness_scale_std: float = DEFAULT_SCALE_STD
    tension_scale: float = 1.0
    tension_scale_std: float = DEFAULT_SCALE_STD
    hours_since_wrapping: float = 0.0
    #: Relative to the load's give as given (a calibrated give is already in the load).
    give_std: float = DEFAULT_GIVE_STD

    @classmethod
    def of(cls, calibration: Calibration | None, hours_since_wrapping: float) -> Uncertainty:
        """Spreads from a calibration where it gives them, the defaults elsewhere."""
        std = {p: (DEFAULT_FRICTION_STD, DEFAULT_FRICTION_STD) for p in PAIRS}
        if calibration is None:
            return cls(std, hours_since_wrapping=hours_since_wrapping)
        for name, pair in calibration.friction.items():
            std[name] = (pair.static_std or DEFAULT_FRICTION_STD,
                         pair.kinetic_std or DEFAULT_FRICTION_STD)
        give_std = calibration.give_scale_std / calibration.give_scale
        return cls(std, calibration.stiffness_scale,
                   calibration.stiffness_scale_std or DEFAULT_SCALE_STD,
                   calibration.tension_scale, calibration.tension_scale_std or DEFAULT_SCALE_STD,
                   hours_since_wrapping, give_std or DEFAULT_GIVE_STD)

    def nominal(self, wrap: WrapFormat) -> WrapFormat:
        """The wrap as the bench simulates it at the nominal values."""
        return wrap.scaled(self.stiffness_scale, self.tension_scale).relaxed(
            self.hours_since_wrapping)

    def draw(self, load: LoadUnit, seed: int) -> Sample:
        """One sample of every uncertain parameter (`seed` fixes it)."""
        rng = np.random.default_rng(seed)
        pairs = {}
        for name in PAIRS:
            pairs[name] = draw_pair(rng, load.friction.pair(name), *self.friction_std[name])
        return Sample(
            friction=pairs,
            mass_scale=float(rng.uniform(1 - MASS_SPREAD, 1 + MASS_SPREAD)),
            stiffness_scale=draw_scale(rng, self.stiffness_scale, self.stiffness_scale_std),
            tension_scale=draw_scale(rng, self.tension_scale, self.tension_scale_std),
            relaxation_scale=draw_scale(rng, 1.0, RELAXATION_STD),
            hours_since_wrapping=self.hours_since_wrapping,
            give_scale=draw_scale(rng, 1.0, self.give_std),
        )


@dataclass(frozen=True)
class Sample:
    """One draw of the uncertain parameters, and how it changes a load and a wrap."""

    friction: dict[str, FrictionPair]
    mass_scale: float
    stiffness_scale: float
    tension_scale: float
    relaxation_scale: float
    hours_since_wrapping: float
    give_scale: float = 1.0

    def load(self, load: LoadUnit) -> LoadUnit:
        bundle = replace(load.bundle, mass_kg=load.bundle.mass_kg * self.mass_scale)
        drawn = replace(load, bundle=bundle, friction=replace(load.friction, **self.friction))
        return drawn.with_give(self.give_scale)

    def wrap(self, wrap: WrapFormat) -> WrapFormat:
        """The wrap as this sample lays it: stiffness and tension scaled, then relaxed (the
        tension it loses is scaled by the sample's relaxation draw)."""
        return wrap.scaled(self.stiffness_scale, self.tension_scale).relaxed(
            self.hours_since_wrapping, self.relaxation_scale)

    def to_json(self) -> dict[str, object]:
        return {"friction": {k: asdict(v) for k, v in self.friction.items()},
                "mass_scale": round(self.mass_scale, 4),
                "stiffness_scale": round(self.stiffness_scale, 4),
                "tension_scale": round(self.tension_scale, 4),
                "relaxation_scale": round(self.relaxation_scale, 4),
                "give_scale": round(self.give_scale, 4),
                "hours_since_wrapping": self.hours_since_wrapping}


@dataclass(frozen=True)
class PassProbability:
    """Passes out of samples, and the Wilson score interval of the probability (95 %)."""

    passed: int
    samples: int

    @property
    def estimate(self) -> float:
        return self.passed / self.samples if self.samples else math.nan

    @property
    def interval(self) -> tuple[float, float]:
        n, z = self.samples, Z95
        if n == 0:
            return (0.0, 1.0)
        p = self.passed / n
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
        return (max(0.0, centre - half), min(1.0, centre + half))

    def to_json(self) -> dict[str, float | int]:
        low, high = self.interval
        return {"estimate": round(self.estimate, 4), "low95": round(low, 4),
                "high95": round(high, 4), "passed": self.passed, "samples": self.samples}

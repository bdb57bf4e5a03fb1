"""Calibrated parameters (CAL.json): what `wrapbench calibrate` fits and the bench then uses."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from wrapenv.config import MAX_FRICTION_COEFFICIENT, InputError, Table, read_json
from wrapenv.load import PAIRS, Friction, FrictionPair, LoadUnit

#: CAL.json's keys beside `friction` and `wrap`: the fit's diagnostics (residual, the replays'
#: own scatter, one replay's residual, simulations and what they were for, method), advice on
#: further tests, the bound it was accepted under (acceptance), the prediction errors on
#: recordings that were not fitted (its validation), and the version of wrapbench that fitted
#: it.
DIAGNOSTICS = ("residual_rms_m", "spread_rms_m", "replay_rms_m", "simulations",
               "simulations_by_part", "method", "advice", "validation", "wrapbench_version")
#: The most a default fit leaves its least explained recording unexplained (RMS, metres): a
#: fit past it is refused unless the engineer accepts it under a looser bound.
DEFAULT_MAX_RESIDUAL_M = 0.01


@dataclass(frozen=True)
class CalibratedPair:
    static: float
    kinetic: float
    static_std: float = 0.0
    kinetic_std: float = 0.0
    #: False when the pair never slipped in the recordings: `static` is then only a lower bound.
    identified: bool = True


@dataclass(frozen=True)
class Calibration:
    """CAL.json as the bench uses it: the fitted friction of each pair and the wrap's scales,
    each with its standard deviation, and what the fit left unexplained. `apply` puts it on a
    load unit; `wrapenv.uncertainty` draws `recommend`'s samples within its spreads."""

    friction: dict[str, CalibratedPair] = field(default_factory=dict)
    stiffness_scale: float = 1.0
    tension_scale: float = 1.0
    stiffness_scale_std: float = 0.0
    tension_scale_std: float = 0.0
    #: The load's give (its bundles' corner stiffness) relative to the load file's, and how
    #: uncertain it is: a wrap-stage parameter like the web's stiffness.
    give_scale: float = 1.0
    give_scale_std: float = 0.0
    #: The wrap scales that were measured elsewhere and given to the fit, not
    #: fitted: their standard deviations are 0 because nothing was estimated.
    known: tuple[str, ...] = ()
    #: What the fit left its least explained recording unexplained (RMS, metres; CAL.json's
    #: `acceptance`, 0 when the file does not say).
    unexplained_rms_m: float = 0.0
    #: The recordings near a threshold, whose outcome the fitted values reproduced only now
    #: and then (CAL.json's `acceptance.near_threshold`): a fit can be pulled there.
    near_threshold: tuple[str, ...] = ()

    def warnings(self) -> tuple[str, ...]:
        """What a user of this calibration should know: it was accepted knowingly under a
        looser bound than a default fit's, or on takes near a threshold, where a fit can move
        the coefficients that decide the outcome to where it is the common one."""
        out = []
        if self.unexplained_rms_m > DEFAULT_MAX_RESIDUAL_M:
            out.append(f"the calibration was accepted with {1e3 * self.unexplained_rms_m:.1f} mm"
                       " of a recording unexplained, where a default fit refuses more than "
                       f"{1e3 * DEFAULT_MAX_RESIDUAL_M:g} mm")
        if self.near_threshold:
            out.append(f"the calibration was fitted to {len(self.near_threshold)} take(s) near a "
                       "threshold, whose outcome its values reproduce only now and then: the "
                       "coefficients deciding it may be off by more than their standard "
                       "deviations")
        return tuple(out)

    def wrap_scales(self) -> dict[str, float]:
        """The wrapped unit's scales by the names `calibration.replay.WRAP_SCALES` applies
        them by."""
        return {"stiffness": self.stiffness_scale, "tension": self.tension_scale,
                "give": self.give_scale}

    def apply(self, load: LoadUnit) -> LoadUnit:
        """The load with its friction replaced by the calibrated pairs (`friction_over`) and
        its give scaled (`scale_give`)."""
        return self.scale_give(load.with_friction(self.friction_over(load.friction)))

    def friction_over(self, base: Friction) -> Friction:
        """`base` with the calibrated pairs in place. A pair the recordings never saw slip
        keeps the base value unless its static coefficient is below the bound the recordings
        support: that bound is what the pair held, not what it is (a stopped pallet's sled
        contact is asked only the braking's ~0.1 g, and a bench that took it for the pallet's
        friction let the pallet slide forward when the sled braked)."""
        pairs = {k: FrictionPair(p.static, p.kinetic) for k, p in self.friction.items()
                 if p.identified or p.static > base.pair(k).static}
        return replace(base, **pairs)

    def scale_give(self, load: LoadUnit) -> LoadUnit:
        """The load with its bundles' edges as compliant as the calibration found."""
        return load.with_give(self.give_scale) if self.give_scale != 1.0 else load

    def draw(self, seed: int) -> Calibration:
        """One draw of the calibrated values within their standard deviations (normal and
        independent; a kinetic coefficient kept at or below its static one, a scale above a
        tenth of its value): predictions replayed with draws spread by what the fit could not
        pin as well as by the bench's own scatter. A pair that was not identified keeps its
        bound, a known scale its value (their standard deviations are 0)."""
        rng = np.random.default_rng(seed)
        pairs = {}
        for name, p in self.friction.items():
            if p.identified:
                d = draw_pair(rng, FrictionPair(p.static, p.kinetic), p.static_std, p.kinetic_std)
                p = replace(p, static=d.static, kinetic=d.kinetic)
            pairs[name] = p
        return replace(self, friction=pairs,
                       stiffness_scale=draw_scale(rng, self.stiffness_scale,
                                                  self.stiffness_scale_std),
                       tension_scale=draw_scale(rng, self.tension_scale, self.tension_scale_std),
                       give_scale=draw_scale(rng, self.give_scale, self.give_scale_std))

    def to_dict(self) -> dict:
        """CAL.json's `friction` and `wrap` tables (what `from_dict` reads back)."""
        return {"friction": {name: asdict(pair) for name, pair in self.friction.items()},
                "wrap": {"stiffness_scale": self.stiffness_scale,
                         "tension_scale": self.tension_scale,
                         "stiffness_scale_std": self.stiffness_scale_std,
                         "tension_scale_std": self.tension_scale_std,
                         "give_scale": self.give_scale,
                         "give_scale_std": self.give_scale_std}
                | ({"known": list(self.known)} if self.known else {})}

    @classmethod
    def from_json(cls, path: str | Path) -> Calibration:
        return cls.from_dict(read_json(path), source=str(path))

    @classmethod
    def from_dict(cls, data: dict, source: str = "calibration") -> Calibration:
        top = Table(data, source)
        fr = top.table("friction")
        pairs = {name: _pair(fr.table(name), source) for name in PAIRS if fr.has(name)}
        fr.done()
        wrap = top.table("wrap")
        low, high = SCALE_RANGE
        stiffness = wrap.number("stiffness_scale", 1.0, minimum=low, maximum=high)
        tension = wrap.number("tension_scale", 1.0, minimum=low, maximum=high)
        stds = (wrap.number("stiffness_scale_std", 0.0, minimum=0.0, maximum=high),
                wrap.number("tension_scale_std", 0.0, minimum=0.0, maximum=high))
        give = _give(wrap)
        known = _known(wrap)
        wrap.done()
        unexplained = 0.0
        near: tuple[str, ...] = ()
        if top.has("acceptance"):
            acceptance = top.table("acceptance")
            unexplained = acceptance.number("unexplained_rms_m", 0.0, minimum=0.0)
            near = _near_threshold(acceptance)
            acceptance.ignore("max_residual_m", "least_explained", "explained_by", "excused")
            acceptance.done()
        # how the fit went and how it was checked: for people, the bench does not need them
        top.ignore(*DIAGNOSTICS)
        if not (pairs or top.has("wrap")):
            # all defaults: the load's own friction and wrap, which the user meant to replace;
            # said before any unknown key, which another file (a truth.json) is full of
            raise InputError(source, "friction",
                             "no friction pair and no wrap table: the file calibrates nothing "
                             "(is it a CAL.json, as a calibration writes?)")
        top.done()
        return cls(pairs, stiffness, tension, *stds, *give, known, unexplained, near)


def _pair(t: Table, source: str) -> CalibratedPair:
    """One calibrated contact pair: coefficients and their standard deviations, kinetic at
    most static."""
    most = MAX_FRICTION_COEFFICIENT
    pair = CalibratedPair(
        static=t.number("static", positive=True, maximum=most),
        kinetic=t.number("kinetic", positive=True, maximum=most),
        static_std=t.number("static_std", 0.0, minimum=0.0, maximum=most),
        kinetic_std=t.number("kinetic_std", 0.0, minimum=0.0, maximum=most),
        identified=t.boolean("identified", True),
    )
    t.done()
    if pair.kinetic > pair.static:
        raise InputError(source, t.field("kinetic"),
                         f"kinetic friction {pair.kinetic} exceeds static {pair.static}")
    return pair


#: Drawn coefficients are kept above these (a draw far in a tail is not a friction pair).
MIN_DRAWN_STATIC, MIN_DRAWN_KINETIC = 0.05, 0.04


def draw_pair(rng: np.random.Generator, pair: FrictionPair, static_std: float,
              kinetic_std: float) -> FrictionPair:
    """A friction pair drawn within standard deviations (normal; a coefficient is kept between
    a floor and the largest a file may give, the kinetic one at or below the static one; a
    standard deviation of 0 draws nothing)."""
    static = _normal(rng, pair.static, static_std, MIN_DRAWN_STATIC, MAX_FRICTION_COEFFICIENT)
    return FrictionPair(static, min(static, _normal(rng, pair.kinetic, kinetic_std,
                                                    MIN_DRAWN_KINETIC, MAX_FRICTION_COEFFICIENT)))


def draw_scale(rng: np.random.Generator, value: float, std: float) -> float:
    """A scale drawn within a standard deviation, kept above a tenth of its value (a scale is
    never zero or negative) and within the largest factor CAL.json may give."""
    return _normal(rng, value, std, 0.1 * value, max(value, SCALE_RANGE[1]))


def _normal(rng: np.random.Generator, value: float, std: float, floor: float,
            ceiling: float) -> float:
    return value if std == 0 else min(ceiling, max(floor, float(rng.normal(value, std))))


#: The wrap scales by their names in CAL.json's `wrap.known`.
WRAP_SCALE_NAMES = ("stiffness", "tension", "give")


#: A wrap scale (stiffness, tension, give) lies within these factors of the card's, WRAP.toml's
#: or the load file's value (the bundle's accepted corner stiffness spans about 500 x; the fit
#: searches 1/4 to 4 x): a factor beyond this is a fit gone astray or a typo.
SCALE_RANGE = (0.05, 20.0)


def _give(wrap: Table) -> tuple[float, float]:
    """CAL.json's optional `wrap.give_scale` and `wrap.give_scale_std` (defaults 1 and 0)."""
    low, high = SCALE_RANGE
    return (wrap.number("give_scale", 1.0, minimum=low, maximum=high),
            wrap.number("give_scale_std", 0.0, minimum=0.0, maximum=high))


def _near_threshold(acceptance: Table) -> tuple[str, ...]:
    """CAL.json's optional `acceptance.near_threshold`: the paths of recordings."""
    if not acceptance.has("near_threshold"):
        return ()
    paths = acceptance.array("near_threshold")
    if not all(isinstance(path, str) for path in paths):
        raise acceptance.error("near_threshold", f"must list recording paths (got {paths!r})")
    return tuple(paths)


def _known(wrap: Table) -> tuple[str, ...]:
    """CAL.json's optional `wrap.known`: names of wrap scales that were measured, not fitted."""
    if not wrap.has("known"):
        return ()
    names = wrap.array("known")
    for name in names:
        if name not in WRAP_SCALE_NAMES or names.count(name) > 1:
            raise wrap.error("known", f"must list distinct names of {', '.join(WRAP_SCALE_NAMES)}"
                                      f" (got {names!r})")
    return tuple(names)

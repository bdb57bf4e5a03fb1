"""What recordings can and cannot tell about each contact pair, and which test would tell more.

A pair that never slipped cannot be fitted: the most the recordings say is a lower bound of its
static coefficient, the largest acceleration (in g) it had to transmit. In a stack that bound
is capped: a pair above one that slipped was only asked as much as the slipping pair's kinetic
friction passes up, so raising the level does not load it further. The advice names the test
that would: a higher level where the level is the limit; where a slipping pair below shields
it, a unit in which that pair holds (`SHIELD_REMOVED`: a stopped pallet for a pallet that slid,
an anti-slip sheet under a bottom layer that slid); where columns toppled, a lower unit (a
toppling column passes no more shear down); or, for the sled-pallet pair of a stopped pallet
(only ever loaded by the braking), a test without the stopper.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

from calibration.replay import Observation
from wrapenv.load import PAIRS, Friction, FrictionPair

#: A pair held stuck is set this far above the largest acceleration it had to transmit.
STUCK_MARGIN = 0.15
#: Advised levels are rounded up to this step (g) and lie this far above the bound.
LEVEL_STEP_G, LEVEL_MARGIN_G = 0.05, 0.05


@dataclass(frozen=True)
class Bound:
    """The largest demand (g) a pair transmitted, and what limited it."""

    demand_g: float
    #: "level" (the test's acceleration), "braking" (a stopped pallet's sled contact),
    #: "toppling" (columns toppled, so a higher level loads the bundles' pairs no further), or
    #: the slipping pair below whose kinetic friction capped it
    limited_by: str


def pairs_present(observations: Sequence[Observation]) -> tuple[str, ...]:
    """The contact pairs the recorded loads have (bundle on bundle needs two layers)."""
    layered = any(o.load.stack.layers > 1 for o in observations)
    return tuple(p for p in PAIRS if p != "bundle_bundle" or layered)


def pair_bounds(observations: Sequence[Observation], fitted: Friction,
                slipped: frozenset[str]) -> dict[str, Bound]:
    """Per pair the largest acceleration it had to transmit, backwards under the pulse and
    forwards when the sled brakes; a stopped pallet is held backwards by the stopper, and a
    pair above a slipping one was only asked as much as that pair's kinetic friction passes."""
    return {name: max((_demand(name, obs, fitted, slipped) for obs in observations),
                      key=lambda b: b.demand_g, default=Bound(0.0, "level"))
            for name in PAIRS}


def _demand(name: str, obs: Observation, fitted: Friction, slipped: frozenset[str]) -> Bound:
    """The largest acceleration one recording asked a pair to transmit (see `pair_bounds`):
    capped by a pair below (one of `slipped`) only where that pair slipped in this
    recording."""
    back, forward = obs.peak_accel_g
    stopped = name == "sled_pallet" and obs.load.pallet_stopper
    demand, why = (forward, "braking") if stopped else (max(back, forward), "level")
    if why == "level" and name != "sled_pallet" and obs.toppled:
        why = "toppling"
    for below in PAIRS[:PAIRS.index(name)]:
        if below in slipped & obs.slipped and fitted.pair(below).kinetic < demand:
            demand, why = fitted.pair(below).kinetic, below
    return Bound(demand, why)


def slipped_throughout(name: str, observations: Sequence[Observation], fitted: Friction,
                       slipped: frozenset[str]) -> Bound | None:
    """For a pair that slipped in every recording, the least it was asked to transmit: its
    onset lies below every level, so its static coefficient is bounded only from above (about
    that demand; a layer rocking on the one below passes up a little more). None when some
    recording held it: then its onset is bracketed."""
    if not observations or any(name not in o.slipped for o in observations):
        return None
    return min((_demand(name, o, fitted, slipped) for o in observations),
               key=lambda b: b.demand_g)


def held_stuck(nominal: Friction, bounds: dict[str, Bound], slipped: frozenset[str]
               ) -> Friction:
    """Pairs that never slipped, set where they stick in the replay too."""
    pairs = {}
    for name in PAIRS:
        if name in slipped:
            continue
        pair = nominal.pair(name)
        static = max(pair.static, bounds[name].demand_g + STUCK_MARGIN)
        pairs[name] = FrictionPair(static, static * pair.kinetic / pair.static)
    return replace(nominal, **pairs)


#: A unit in which the slipping pair below (the key) holds, so the pair above is loaded.
SHIELD_REMOVED = {
    "sled_pallet": "the unit with the pallet stopper",
    "pallet_bundle": "the unit with its bottom layer held on the pallet (an anti-slip sheet "
                     "under it)"}


def _level_above(g: float) -> float:
    return math.ceil((g + LEVEL_MARGIN_G) / LEVEL_STEP_G - 1e-9) * LEVEL_STEP_G


#: Said of a test on another set-up: its load file differs, and `calibrate` fits takes of
#: different loads together only when asked.
OTHER_LOAD = " (another load file: fit its take with these using --mixed-loads)"


def advice_unslipped(name: str, bound: Bound) -> str:
    """The test that would make a pair that never slipped slip."""
    if bound.limited_by == "braking":
        return (f"never slipped: the stopper held the pallet, only the braking loaded it "
                f"({bound.demand_g:.2f} g); test without the pallet stopper at "
                f"{_level_above(bound.demand_g):.2f} g or more{OTHER_LOAD}")
    if bound.limited_by == "toppling":
        unit = ("a one-layer unit (bundles on the pallet only)" if name == "pallet_bundle"
                else "a unit of fewer layers")
        return (f"never slipped up to {bound.demand_g:.2f} g while its bundles stood: columns "
                f"toppled first, and a higher level topples them sooner; test {unit} at "
                f"{_level_above(bound.demand_g):.2f} g or more{OTHER_LOAD}")
    if bound.limited_by != "level":
        unit = SHIELD_REMOVED[bound.limited_by]
        return (f"never slipped: {bound.limited_by} slipped first and passed up at most "
                f"{bound.demand_g:.2f} g; a higher level does not load it more; test "
                f"{unit} at {_level_above(bound.demand_g):.2f} g or more{OTHER_LOAD}")
    return (f"never slipped up to {bound.demand_g:.2f} g; test at "
            f"{_level_above(bound.demand_g):.2f} g or more")


def _level_below(g: float) -> float:
    return math.floor((g - LEVEL_MARGIN_G) / LEVEL_STEP_G + 1e-9) * LEVEL_STEP_G


def advice_static(name: str, observations: Sequence[Observation], std: float,
                  unrefused: Sequence[float] = ()) -> str:
    """For a pair that slipped whose static coefficient the recordings do not resolve;
    `unrefused`: shifts of the fitted value the acceptance test allowed (`fit._probe`)."""
    first = min(o.peak_accel_g[0] for o in observations if name in o.slipped)
    low = max((o.peak_accel_g[0] for o in observations
               if name not in o.slipped and o.peak_accel_g[0] < first), default=None)
    why = _not_refused(unrefused)
    if low is None:
        return (f"static coefficient not resolved (± {std:.3f}{why}): a level below "
                f"{first:.2f} g, where it starts to slip, would bracket it")
    return (f"static coefficient not resolved (± {std:.3f}{why}): its onset lies between "
            f"{low:.2f} and {first:.2f} g; a level between them may narrow it, unless the layers "
            "below rock (then the slip above is set by their rocking)")


def _not_refused(unrefused: Sequence[float]) -> str:
    """The shifts of a fitted value the acceptance test allowed, as the advice says them."""
    if not unrefused:
        return ""
    return "; the recordings do not refuse it shifted " + " or ".join(
        f"{d:+.3f}" for d in sorted(unrefused))


def highest_slipped_g(name: str, observations: Sequence[Observation]) -> float:
    """The highest level (peak acceleration, g) of the recordings in which the pair slipped."""
    return max(o.peak_accel_g[0] for o in observations if name in o.slipped)


def slipped_at_one_level(name: str, observations: Sequence[Observation]) -> bool:
    """Whether the recordings in which the pair slipped were all made at one level: then a
    later onset and a freer slide run as far, and its two coefficients trade along a ridge."""
    return len({round(o.peak_accel_g[0], 3) for o in observations if name in o.slipped}) == 1


def advice_kinetic(name: str, observations: Sequence[Observation], std: float,
                   unrefused: Sequence[float] = ()) -> str:
    """For a pair that slipped whose kinetic coefficient the recordings do not resolve: how far
    a slip runs pins it, and a higher level makes it run farther. Slipped at one level, a later
    onset and a freer slide run as far (the one-layer unit at 0.50 g: the truth with its static
    coefficient 0.03 higher and its kinetic one 0.04 lower leaves 2.2 mm unexplained). A level
    where a front row slides off its support still pins it through the bundles behind, which
    slide on (a body is judged until its centre leaves what it rests on,
    `calibration.features`; docs/calibration.md, "Pallet–bundle's ridge"). `unrefused`: shifts
    of the fitted value the acceptance test allowed, the others refitted (`fit._probe`)."""
    why = _not_refused(unrefused)
    trade = (", but slipping at one level only, a later onset and a freer slide run as far "
             "(its static coefficient trades against it)"
             if slipped_at_one_level(name, observations) else "")
    return (f"kinetic coefficient not resolved (± {std:.3f}{why}): how far a slip runs pins "
            f"it{trade}; a level above {highest_slipped_g(name, observations):.2f} g, where it "
            "runs farther, would narrow it while some bundle that slips on it keeps its support "
            "there")


def advice_slipped_throughout(bound: Bound, static: float, std: float) -> str:
    """For a pair that slipped at every level (`slipped_throughout`)."""
    return (f"slipped at every level, already under {bound.demand_g:.2f} g: the recordings "
            f"bound its static coefficient only from above (about {bound.demand_g:.2f}; more "
            f"where the layers below rock and pass up more than the sled's level), so "
            f"the fitted {static:.3f} is not resolved (± {std:.3f} over kinetic to that bound); "
            f"test at {_level_below(bound.demand_g):.2f} g or lower, where it holds")


def advice_scale(name: str, scale: float, std: float, paper: bool,
                 carried: bool = False) -> str:
    """For a wrap scale the recordings do not resolve, with the reason that fits the web: a
    paper web is much stiffer than the load's edges, whose give then decides the motion; a film
    is much softer, so its stiffness does show (LLDPE: x2 moves the 0.7 g take's features 3-5
    mm), but only together with the laid tension and the give in series with it: fitted with
    the true friction, the LLDPE take gave stiffness 3.9 x, tension 0.6 x and give 0.3 x for the
    truth's 1.3, 1 and 1, and predicted the held-out take within 5 %; with the tension and the
    give known, +15 % and +14 % over two fit seeds; a second wrapped level instead, +13 to +120 %
    over three (docs/calibration.md).
    What is measured elsewhere is given as known (`calibrate --known`). `carried`: the wrapped
    takes were filmed after earlier levels on the same unit, whose replays scatter several
    times more than a fresh unit's (the film-wrapped 2-layer unit at 0.5 g after 0.2-0.4 g:
    +- 4.2 mm against +- 0.4 mm fresh): with the true friction and the tension and give known,
    LLDPE's stiffness came out +61 to +115 % from such a take, -3 to +11 % from a fresh one."""
    hardly = "the recorded motion hardly depends on it"
    known = "give it as known (--known)"
    if name == "stiffness" and paper:
        why = (f"{hardly}: where the web is much stiffer than the load-side compliance in series "
               "with it (paper on shrink-wrapped bundles), that compliance decides how far the "
               "load moves; take the web's stiffness from its tensile test")
    elif name == "stiffness":
        why = ("the film decides how far the load moves, but these takes constrain its stiffness "
               "only together with its laid tension and the load's give in series with it: "
               f"measure the laid tension (or the containment force) and the give and {known}")
    elif name == "tension" and not paper:
        why = ("these takes constrain it together with the film's stiffness: measure the laid "
               f"tension (or the containment force) and {known}")
    elif name == "give" and not paper:
        why = ("these takes constrain it only together with the film's stiffness, in series with "
               "it: measure it (a plate pressed on a bundle's edge, docs/materials.md B1) and "
               f"{known}")
    else:
        why = hardly
    if carried:
        why += ("; the wrapped takes were filmed after earlier levels of the same unit, whose "
                "replays scatter several times more than a fresh unit's: for the wrap, film a "
                "freshly stacked and wrapped unit")
    return f"{name} scale not resolved ({scale:.2f} ± {std:.2f}): {why}"


def advice_scale_at_fitted_friction(name: str, scale: float, std: float) -> str:
    """For a wrap scale the fit resolves with the friction it fitted in the same run held: the
    scale's standard deviation leaves that friction's out, and a take the wrap moves, friction
    moves too. LLDPE's stiffness (tension and give known) was reported resolved at +26 and
    +31 %, 1.4 and 1.5 of its standard deviations off, where the true friction gave +1 and -1 %;
    the true friction shifted by one fit's errors (each 0.01 or less) moved it by +24 to +27 %
    (docs/calibration.md, "How far friction's error moves the film's stiffness"). Carrying the
    friction's covariance into the wrap stage (its design spread over it) was tried and not
    kept: it missed two of three such errors and made the estimates worse."""
    return (f"{name} scale {scale:.2f} ± {std:.2f} holds only at the friction fitted with it: "
            "its ± leaves that friction's uncertainty out, and friction errors of 0.01 moved "
            "a film's stiffness by a quarter; to trust it, fit the wrap alone (--params wrap) "
            "on a load file whose friction was measured elsewhere, or check it on a held-out "
            "take (--validate)")

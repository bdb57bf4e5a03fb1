"""What a robust search searches: its settings, and the problem the workers simulate.

`Problem` holds the load, its layout, the program space, the uncertainty and the objective
(minimised, `Problem.objective`): the kg of web laid relative to the machine's default program,
plus a penalty that grows with the shortfall of the worst sample's margin below the wanted
margin, the heaviest program's web for a failure, an optional price on cycle time and a small
one on tension; a program slower than the cycle-time limit is rejected without a simulation.
Picklable and free of Bullet state, so it travels to worker processes.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from wrapenv.bench import SimSettings
from wrapenv.calibrated import Calibration
from wrapenv.design import INTEGER_INDICES, TENSION_INDICES, ProgramSpace
from wrapenv.eumos import EUMOS_LIMITS, Limits
from wrapenv.load import Layout, LoadUnit, Orientation
from wrapenv.profile import PulseProfile
from wrapenv.uncertainty import TRANSPORT_HOURS, Sample, Uncertainty
from wrapenv.wrap import Web, WrapFormat

#: Objective penalty per unit of margin shortfall (below the margin goal): a tenth of margin is
#: worth the web of one machine-default program.
PENALTY_PER_MARGIN = 10.0
#: Objective of a program slower than the cycle-time limit (times 1 + its relative excess):
#: worse than any simulated candidate, so the search moves back under the limit. A margin has
#: no lower bound (a unit that topples moves metres against a limit of centimetres: -8 was
#: seen), so this is far above any objective a margin gives; CMA-ES ranks, so its size is free.
SLOW_PENALTY = 1e6
#: Objective per unit of mean tension (as a fraction of the searched range): a tie-breaker,
#: among programs of equal web the gentler one is kinder to the web at the load's corners.
TENSION_PRICE = 0.05

#: A load is only as safe as its weaker orientation: road rules ask 0.8 g forward and 0.5 g
#: sideways and rearward (EN 12195-1); the default searches both sides at 0.5 g.
BOTH_SIDES: tuple[tuple[Orientation, float], ...] = (("long", 0.5), ("short", 0.5))


@dataclass(frozen=True)
class SearchSettings:
    """How `recommend` searches: what a program must pass and with what margin, on which web,
    in how many samples, at what budget; `identity` is what a checkpoint must match."""

    #: (orientation, target level in g) pairs every candidate must pass.
    targets: tuple[tuple[Orientation, float], ...] = BOTH_SIDES
    #: The web a program is sought for (card, width, machine).
    web: Web = Web.named("kraft")
    samples: int = 3               # K robust samples per candidate
    margin_goal: float = 0.2       # wanted margin of the worst sample (0.2: 80 % of each limit)
    popsize: int = 8
    max_candidates: int = 48
    #: Stop after this many generations without a lighter robust pass.
    patience: int = 3
    sigma0: float = 0.3
    seed: int = 0
    workers: int = max(1, os.cpu_count() or 1)
    backend: str = "process"       # "process" (this machine) or "ray"
    ray_address: str | None = None  # None: a local Ray instance; "auto" or "ray://...": a cluster
    max_cycle_s: float = math.inf  # programs slower than this are rejected
    cycle_weight: float = 0.0      # objective per second of cycle, in reference masses
    hours_since_wrapping: float = TRANSPORT_HOURS
    #: The default fidelity: confirmations and the verification.
    sim: SimSettings = SimSettings()
    #: The fidelity candidates are screened with; None: every candidate at `sim`.
    screen: SimSettings | None = SimSettings.screening()
    #: Samples a candidate is screened in (the first of the K); a confirmation runs all K. One:
    #: on the bundled example the search then asks the same candidates and finds the same
    #: answer as screening in all three, with half the simulations (benchmarks/bench_recommend.py).
    screen_samples: int = 1
    #: The criteria a level is judged by (EUMOS 40509's, optionally a layer-shift limit).
    limits: Limits = EUMOS_LIMITS
    #: Verify on a fresh unit per level instead of one unit through the sequence, as a lab.
    fresh: bool = False
    #: Lay every zone at the top of the tension range (the search then chooses wraps, overlap
    #: and the reinforcement's height only): what a later round does (`in_round`).
    top_tension: bool = False
    #: Lay the bottom and the top wraps at least as tight as the spiral, as machine practice
    #: and the source paper's model order the zones (hardest at the bottom, a little harder at
    #: the top than in the middle). Off, each zone's tension is searched freely, and an answer
    #: may lay its bottom wraps looser than its spiral (docs/recommend.md).
    ordered_tensions: bool = True

    @property
    def target_g(self) -> float:
        """The highest target of any orientation."""
        return max(g for _, g in self.targets)

    def in_round(self, number: int) -> SearchSettings:
        """The settings of search round `number` (1: these). A round follows one whose passes
        all failed their verification, or that found none: those passes held in the search's
        few samples by chance, so each round tries every candidate in one more sample, with
        twice the budget for the sturdier passes to be found (film on the 2-layer columnar
        example: no answer at 3 samples and 48 candidates, 0.076 kg at 4 and 96;
        docs/recommend.md), and lays every zone at the top of the tension range. Tension costs
        no web, and a search's tensions drift low (nothing in its few samples asks for more,
        and its tie-breaker prefers the gentler): on a 1-layer film unit of the held-out set
        five bottom wraps and a top wrap at 58 N held in 4 of 8 verification samples, at 94 N
        in 8 of 8, and the first round's three passes (37-90 N) in 4-6 of 8."""
        if number < 1:
            raise ValueError(f"a search round is numbered from 1 (got {number})")
        extra = number - 1
        return replace(self, samples=self.samples + extra,
                       max_candidates=self.max_candidates * 2 ** extra,
                       top_tension=self.top_tension or number > 1)

    def identity(self) -> dict[str, Any]:
        """What makes two searches the same search (a checkpoint must match it)."""
        return {"targets": [list(t) for t in self.targets], "material": self.web.identity(),
                "hours_since_wrapping": self.hours_since_wrapping, "samples": self.samples,
                "margin_goal": self.margin_goal, "popsize": self.popsize,
                "sigma0": self.sigma0, "seed": self.seed, "max_cycle_s": _json_float(
                    self.max_cycle_s), "cycle_weight": self.cycle_weight,
                "sim": asdict(self.sim),
                "screen": None if self.screen is None else asdict(self.screen),
                "screen_samples": self.screen_samples,
                **({} if self.limits.layer_shift_fraction is None else
                   {"layer_shift_limit": self.limits.layer_shift_fraction}),
                **({"top_tension": True} if self.top_tension else {}),
                **({"ordered_tensions": True} if self.ordered_tensions else {})}


@dataclass(frozen=True)
class Problem:
    """What the workers need: picklable, no Bullet state."""

    load: LoadUnit
    layout: Layout
    uncertainty: Uncertainty
    space: ProgramSpace
    settings: SearchSettings
    reference_mass_kg: float
    #: Web of the heaviest program of the space, in reference masses.
    heaviest_ratio: float

    @classmethod
    def build(cls, load: LoadUnit, settings: SearchSettings,
              calibration: Calibration | None = None) -> Problem:
        if calibration is not None:
            load = calibration.apply(load)
        for _, target in settings.targets:
            PulseProfile(target)  # validates every target against the bench
        layout = load.layout()
        space = ProgramSpace.for_layout(layout, settings.web)
        reference = space.reference_mass_kg(layout)
        heaviest = space.wrap(space.high).material_used_on(layout).mass_kg / reference
        uncertainty = Uncertainty.of(calibration, settings.hours_since_wrapping)
        return cls(load, layout, uncertainty, space, settings, reference, heaviest)

    def in_round(self, number: int) -> Problem:
        """The problem of search round `number` (`SearchSettings.in_round`)."""
        return replace(self, settings=self.settings.in_round(number))

    def values(self, x: np.ndarray) -> np.ndarray:
        """ProgramSpace values of a search vector: wraps as they are, the continuous
        coordinates from fractions of their range (the tensions at its top with
        `SearchSettings.top_tension`, whatever the vector says; with `ordered_tensions` the
        bottom and top wraps' at least the spiral's, so a coordinate keeps its meaning and a
        checkpoint or a policy's proposal its vector)."""
        lo, hi = self.space.low, self.space.high
        v = lo + np.asarray(x, float) * (hi - lo)
        v[list(INTEGER_INDICES)] = np.asarray(x, float)[list(INTEGER_INDICES)]
        if self.settings.top_tension:
            v[list(TENSION_INDICES)] = hi[list(TENSION_INDICES)]
        if self.settings.ordered_tensions:
            bottom, middle, top, _ = TENSION_INDICES
            v[[bottom, top]] = np.maximum(v[[bottom, top]], v[middle])
        return v

    def vector(self, wrap: WrapFormat) -> tuple[float, ...]:
        """The search vector of a program of this space (`values`' inverse), where a search
        starts from a policy's proposal. A coordinate whose range is a single value (a unit
        too low for a reinforcement's height to vary) is 0."""
        if wrap.program is None:
            raise ValueError("a search starts from a program, not from bands")
        v = self.space.values(wrap.program)
        lo, hi = self.space.low, self.space.high
        span = np.where(hi > lo, hi - lo, 1.0)
        x = np.clip((v - lo) / span, 0.0, 1.0)
        x[list(INTEGER_INDICES)] = v[list(INTEGER_INDICES)]
        return tuple(float(c) for c in x)

    def wrap(self, x: np.ndarray) -> WrapFormat:
        """The program to enter into the machine (what `--wrap-out` writes)."""
        return self.space.wrap(self.values(x))

    def simulated(self, wrap: WrapFormat) -> WrapFormat:
        """The wrap as the (calibrated) bench sees it at the nominal values: stiffness and
        tension scaled, tension relaxed for the hours since wrapping."""
        return self.uncertainty.nominal(wrap)

    def sample(self, seed: int) -> Sample:
        """The uncertain parameters drawn for one seed."""
        return self.uncertainty.draw(self.load, seed)

    def objective(self, wrap: WrapFormat, mass_kg: float, margins: list[float],
                  passed: list[bool]) -> float:
        """Web relative to the machine's default program, a penalty for the margin shortfall,
        a price on cycle time (if asked) and on tension (a tie-breaker). A failure in any
        sample also pays the web of the heaviest program of the space, so it never scores
        better than a pass."""
        s = self.settings
        shortfall = max(0.0, s.margin_goal - min(margins))
        t0, t1 = self.space.tension_range_n
        tension = np.mean([(p.tension_n - t0) / (t1 - t0) for p in wrap.passes])
        failed = 0.0 if all(passed) else self.heaviest_ratio
        return (mass_kg / self.reference_mass_kg + PENALTY_PER_MARGIN * shortfall + failed
                + s.cycle_weight * wrap.cycle_time_s + TENSION_PRICE * float(tension))

    def too_slow(self, wrap: WrapFormat) -> float | None:
        """The objective of a program over the cycle-time limit, None if within it."""
        limit = self.settings.max_cycle_s
        cycle = wrap.cycle_time_s
        return None if cycle <= limit else SLOW_PENALTY * (1 + (cycle - limit) / limit)


def _json_float(x: float) -> float | str:
    return x if math.isfinite(x) else "inf"


__all__ = ["BOTH_SIDES", "PENALTY_PER_MARGIN", "SLOW_PENALTY", "TENSION_PRICE", "Problem",
           "SearchSettings"]

"""Gymnasium environments of the virtual bench: choose a wrapping program, see it tested.

One step is one wrapping program laid on a load unit and put through the bench (EUMOS 40509
sequence or only the target level); the episode then ends. `WrapBenchEnv` keeps one load unit,
`WrapBenchRandomEnv` draws a new one at every reset. See the class docstrings for the spaces,
the reward and the arguments.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from wrapenv.bench import BenchRun, SimSettings, run_levels
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError, is_finite_number, is_real_number
from wrapenv.design import N_PARAMS, ProgramSpace
from wrapenv.envs import random_units
from wrapenv.envs.observation import OBS_FEATURES, OBS_NAMES, observe
from wrapenv.eumos import Verdict
from wrapenv.load import EXAMPLE_LOAD, Layout, LoadUnit, Orientation
from wrapenv.material import MATERIALS, check_hours_since_wrapping
from wrapenv.profile import eumos_levels
from wrapenv.render import Renderer, fitting_camera, rest_state, torn_net
from wrapenv.scene import BUNDLES, PALLET
from wrapenv.trace import Trace
from wrapenv.uncertainty import Sample, Uncertainty
from wrapenv.wrap import WrapFormat

LEVEL_MODES: tuple[str, ...] = ("eumos", "target")
#: None: the side the load file lays along the motion; "random": one drawn at every reset.
ORIENTATIONS: tuple[str | None, ...] = (None, "long", "short", "random")
SIDES: tuple[Orientation, ...] = ("long", "short")

#: Rendered frames: a small side camera (the recordings' camera model, wrapenv.render).
RENDER_SIZE = (480, 300)


class WrapBenchEnv(gym.Env):
    """
    ## Description
    The virtual EUMOS 40509 acceleration bench (ESTL sled) as a one-step decision problem: the
    agent chooses a wrapping program (what a spiral wrapper runs: bottom wraps, a spiral up,
    top wraps, a reinforcement, a tension per zone) for a pallet load unit; the machine's web is
    laid, the bench runs the test and judges it, and the reward says whether the unit passed,
    by how much, and how much web the program laid. Passing with less web scores higher.

    ## Action Space
    `Box(-1, 1, (9,), float32)`, mapped linearly onto the ranges of
    `wrapenv.design.ProgramSpace` for the unit and the `material` (its module docstring is the
    reference), whole numbers of wraps rounded:

    | index | meaning                                         | -1 ... 1 maps to                  |
    |-------|-------------------------------------------------|-----------------------------------|
    | 0     | bottom wraps (carriage parked at the sled)      | 1 ... 6 (one holds the head)      |
    | 1     | top wraps (web 5 cm above the load, folded)     | 1 ... 6                           |
    | 2     | reinforcement wraps (0: none)                   | 0 ... 4                           |
    | 3     | spiral up overlap                               | 0 ... 0.75 (1 to 4 layers)        |
    | 4     | reinforcement's lower edge                      | bottom wraps' ... load top - web  |
    | 5-8   | tension: bottom, spiral, top, reinforcement     | 5 % ... 50 % of one layer's yield |

    Values outside [-1, 1] are clipped (5.0 acts as 1.0); a NaN (or infinite) value raises
    `ValueError`, as does a vector of another length.

    ## Observation Space
    `Box(0, high, (31,), float32)`: features of the load unit, the task and the web, constant
    within an episode (the "state" is the unit the program is for). Scales are divisors:

    | index | feature                                                     | scale         |
    |-------|-------------------------------------------------------------|---------------|
    | 0     | layers of bundles                                           | / 4           |
    | 1-3   | bundle length, width, height                                | / 0.5 m       |
    | 4     | bundle mass                                                 | / 20 kg       |
    | 5-7   | pallet length, width, height                                | / 1.2 m       |
    | 8     | load height (sled surface to top of the load)               | / 2 m         |
    | 9-11  | pattern one-hot: columnar, interlocked, explicit            | 0 or 1        |
    | 12-17 | friction static, kinetic of sled_pallet, pallet_bundle,     | coefficient   |
    |       | bundle_bundle (as simulated: calibration applied)           |               |
    | 18    | target level                                                | g             |
    | 19-24 | calibration standard deviation of each of 12-17             | coefficient   |
    |       | (0 without a calibration, or for a pair it does not give)   |               |
    | 25    | web grammage                                                | / 0.1 kg/m²   |
    | 26    | log10 of the web's stiffness (N/m per unit strain)          | / 6           |
    | 27-28 | yield strain, break strain                                  | as is         |
    | 29    | breaking force per metre of web                             | / 10 kN/m     |
    | 30    | 1 for paper (no cling, no pre-stretch), 0 for film          | 0 or 1        |

    The web is described by its card's figures, not by its name, so a new material card keeps
    the observation's shape. Upper bounds of the space: 10 for indexes 0-8 and 25-29, 2 for
    friction and its std, 1.1 g for the target, 1 for the one-hots (`OBS_FEATURES`); a load
    whose features fall outside is rejected at construction with `InputError`.

    ## Rewards
    With `m` = `Verdict.margin` (the smallest of 1 - figure / limit over the elastic, permanent
    and lowest-20-cm displacements, over the levels run; -1 at best with damage, -1 for an
    invalid simulation) and `ratio` = kg of web the program laid / reference mass (the web of
    the machine's default program on this unit: 3 bottom wraps, a 50 % spiral, 3 top wraps,
    `reference_mass_kg`):

        reward = reward_verdict + reward_material
        reward_verdict  =  1 + min(m, 0.5)    if the unit passed every level run
                          -1 + max(m, -1)     otherwise (failed, damaged, or invalid)
        reward_material = -material_weight * ratio

    `reward_verdict` is in [1, 1.5] for a pass (m >= 0) and in [-2, -1] for a failure (m <= 0);
    the cap at 0.5 stops rewarding margin beyond half the limits, so among safe programs the
    cheaper wins. With `material_weight <= 1` a pass scores above every failure whose program
    lays at most 2 x the default's web less; the heaviest programs of the space lay 2.45-2.67 x
    it (1-3 layers), so they alone can score below a light program's failure.
    A simulation that blew up (`info["valid"] is False`) is rewarded as a failure with m = -1.
    The two terms are returned in `info["reward_terms"]` (keys "verdict" and "material").
    With `tests_per_episode` K > 1 the program is put through K tests, each with its own drawn
    side and sample, and `m` and the pass are the worst test's (a failure before a pass, a
    blown-up run before a failure, then the smallest margin): the episode is judged as a
    recommendation is verified, every sample must hold, so a program failing one sample in
    eight costs about K eighths of a failure, not one.

    ## Starting State
    The load unit stacked on the still sled, unwrapped. At the defaults `WrapBenchEnv` has no
    randomness: every reset returns the same observation. (`WrapBenchRandomEnv` draws a new unit
    from `self.np_random`.) With `orientation="random"` each reset draws the side that meets the
    motion, and with `uncertain=True` one sample of what the bench does not know
    (`wrapenv.uncertainty`: friction, bundle mass, the web's stiffness and laid tension, the
    load's give, relaxation), both from `self.np_random` (a side and a sample for each of the
    `tests_per_episode` tests, test by test). Neither is observed: the observation
    is the unit as its file gives it, so a policy trained so learns one program that holds on
    either side and whatever the sample, which is how its proposal is verified.

    ## Episode End
    After one step: `terminated=True`, `truncated=False`. Stepping again without a reset tests
    another format on the same unit (the env keeps no state between steps), but agents should
    reset. The ids are registered without a time limit, so `truncated` stays False under
    `gymnasium.make` too.

    ## Info
    `reset`: "load" (the unit's name), "reference_mass_kg", "orientation" (the side tested:
    "long", "short", or None for the file's own), "sample" (`Sample.to_json`, or None). `step`:
    "format" (the program and the bands it laid, before calibration scaling), "verdict" (the
    run's verdict, `Verdict.to_json`), "material_used" (area_m2, mass_kg, web_length_m,
    roll_length_m, revolutions), "cycle_time_s", "passed", "margin", "valid", "material_ratio",
    "reward_terms", "tests_passed" (of the `tests_per_episode`), "orientation" and "sample" (of
    the test that judged the step; at reset, of the first test).

    ## Arguments
    `gymnasium.make("wrapenv/WrapBench-v3", **kwargs)`, all keyword-only and checked at
    construction: `InputError` (a `ValueError`) for a bad value of a number or a name, a string
    given for a number included; `TypeError` for a `load`, `calibration` or `settings` of
    another type:

    | argument          | default                           | meaning                              |
    |-------------------|-----------------------------------|--------------------------------------|
    | `load`            | examples/pet_2layer_columnar.toml | LOAD.toml path or a `LoadUnit`       |
    | `calibration`     | None                              | CAL.json path, `Calibration` or None |
    | `material`        | "kraft"                           | "kraft" or "lldpe"                   |
    | `target_g`        | 0.5                               | target level, g (bench max 1.019)    |
    | `start_g`         | None: 0.2 g (the target if lower) | first level of the EUMOS sequence    |
    | `levels`          | "eumos"                           | "eumos": start_g, +0.1 g ... target, |
    |                   |                                   | stop at the first failure (the       |
    |                   |                                   | spec); "target": the target only     |
    |                   |                                   | (3-4x faster, for training)          |
    | `material_weight` | 1.0                               | weight of the material term (>= 0)   |
    | `orientation`     | None: as the load file lays it    | "long", "short" side along the       |
    |                   |                                   | motion, or "random" (drawn per reset)|
    | `hours_since_wrapping` | 0.0                          | the wrap tested after relaxing this  |
    |                   |                                   | long (16: `recommend`'s transport)   |
    | `uncertain`       | False                             | True: each reset draws one sample of |
    |                   |                                   | what the bench does not know         |
    | `tests_per_episode` | 1                               | tests of each step's program, each   |
    |                   |                                   | its own side and sample, judged by   |
    |                   |                                   | the worst (> 1 needs a drawn side or |
    |                   |                                   | sample; at most 16)                  |
    | `render_mode`     | None                              | None or "rgb_array"                  |
    | `settings`        | `SimSettings()`                   | numerical settings of the bench      |

    A calibration replaces the load's friction by its pairs (`Calibration.apply`) and scales the
    web's stiffness and wrapping tension (`stiffness_scale`, `tension_scale`) in the simulation.
    Pass paths rather than objects to vector envs (`gymnasium.make_vec(..., load="x.toml")`):
    they pickle small and read the same file in every worker.

    Numbers may be NumPy scalars. `gym.make(..., render_mode="human")` wraps the env in
    Gymnasium's `HumanRendering` (which needs pygame) before the env sees the mode; the env
    itself takes only "rgb_array".

    `render()` ("rgb_array") returns a 480 x 300 RGB uint8 frame from the recordings' side
    camera: the unit as stacked before a step, else the last tested unit in the final state of
    its last level with the wrap drawn over it (elements at the heights the verdict reports
    torn are drawn torn).

    ## Version History
    * v3: the bottom wraps' web starts a few cm onto the pallet (`wrapenv.design.ONTO_PALLET_M`
      below its top), clear of its fork entries, and a reinforcement no lower; it started at
      the sled surface, covering them.
    * v2: every program has at least one bottom and one top wrap (actions 0 and 1 map onto
      1 ... 6, were 0 ... 6): paper's head is held only by a revolution laid over it, and the
      web then closes round the load at every height (`wrapenv.design`).
    * v1: the action is a wrapping program (9 parameters, whole numbers of wraps) whose web is
      costed as the machine lays it, every revolution a full web width; the reward's reference
      is the machine's default program; the material is observed by its card's figures (31
      features, the same shape for any card).
    * v0: initial version (one-step episodes, 8-parameter three-band formats of arbitrary
      height, 27 features with a material one-hot). Removed: no spiral wrapper lays such bands.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}
    #: True: the unit is drawn at every reset (none exists before the first one).
    draws_units = False

    def __init__(
        self,
        *,
        load: str | Path | LoadUnit | None = None,
        calibration: str | Path | Calibration | None = None,
        material: str = "kraft",
        target_g: float = 0.5,
        start_g: float | None = None,
        levels: str = "eumos",
        material_weight: float = 1.0,
        orientation: str | None = None,
        hours_since_wrapping: float = 0.0,
        uncertain: bool = False,
        tests_per_episode: int = 1,
        render_mode: str | None = None,
        settings: SimSettings | None = None,
    ) -> None:
        super().__init__()
        self.render_mode = _one_of("render_mode", render_mode, (None, "rgb_array"))
        self.material = _one_of("material", material, tuple(MATERIALS))
        self.target_g = _level("target_g", target_g)
        self.start_g = None if start_g is None else _level("start_g", start_g)
        with _as_arguments():
            self._sequence = eumos_levels(self.target_g, self.start_g)
            self.hours_since_wrapping = check_hours_since_wrapping(hours_since_wrapping)
        self.levels = _one_of("levels", levels, LEVEL_MODES)
        self.material_weight = _material_weight(material_weight)
        self.settings = _settings(settings)
        self.calibration = _calibration(calibration)
        self.orientation = _one_of("orientation", orientation, ORIENTATIONS)
        self.uncertain = _one_of("uncertain", uncertain, (False, True))
        self.uncertainty = Uncertainty.of(self.calibration, self.hours_since_wrapping)
        self.tests_per_episode = _tests_per_episode(tests_per_episode, self.orientation == "random"
                                                    or self.uncertain)

        self.action_space: spaces.Box = spaces.Box(-1.0, 1.0, (N_PARAMS,), np.float32)
        high = np.array([h for _, h in OBS_FEATURES], np.float32)
        self.observation_space: spaces.Box = spaces.Box(np.zeros_like(high), high,
                                                        dtype=np.float32)

        self._renderer: Renderer | None = None
        #: The last step's final trace, the wrap and the unit it tested (laid out for rendering)
        self._last: tuple[Trace, WrapFormat, LoadUnit] | None = None
        #: The side and the sample of each of the episode's tests: fixed, or drawn at reset
        #: (`_draw_tests`); `_side` and `_sample` are the test shown (in info, by `render`): the
        #: first before a step, the one that judged it after.
        self._fixed_side: Orientation | None = (self.orientation if self.orientation in SIDES
                                                else None)
        self._tests: list[tuple[Orientation | None, Sample | None]] = [(self._fixed_side, None)]
        self._side, self._sample = self._tests[0]
        self._drawn = False   # until reset: Gymnasium's order, whichever the mode
        self.unit: LoadUnit | None = None  # the unit as simulated (calibration applied)
        self.layout: Layout | None = None
        self.program_space: ProgramSpace | None = None
        self.reference_mass_kg = math.nan
        self._obs = np.zeros(len(OBS_FEATURES), np.float32)
        if not self.draws_units:
            self._set_unit(self._calibrated(_load_unit(load)))

    # -- the unit -------------------------------------------------------------------------
    def _calibrated(self, load: LoadUnit) -> LoadUnit:
        return self.calibration.apply(load) if self.calibration is not None else load

    def _set_unit(self, unit: LoadUnit) -> None:
        """Make `unit` (friction as simulated) the unit programs are tested on."""
        layout = unit.layout()
        space = ProgramSpace.for_layout(layout, self.material)
        obs = observe(unit, layout, self.target_g, MATERIALS[self.material],
                      self.calibration)
        outside = np.flatnonzero(~((obs >= 0) & (obs <= self.observation_space.high)))
        if len(outside):
            i = int(outside[0])
            raise InputError(unit.name, "load", f"observation feature {i} ({OBS_NAMES[i]}) is "
                             f"{obs[i]:.3f}, outside [0, {self.observation_space.high[i]:g}]")
        self.unit, self.layout, self.program_space = unit, layout, space
        self.reference_mass_kg = space.reference_mass_kg(layout)
        self._obs = obs
        self._last = None

    def _require_unit(self) -> None:
        if self.unit is None:
            raise ResetNeeded("call reset() before step() or render(): the load unit is drawn "
                              "at reset")

    def _draw_tests(self) -> None:
        """The side and sample of each of the episode's tests, when drawn (after the unit, from
        the same stream, test by test: side, then sample)."""
        if self.orientation == "random" or self.uncertain:
            self._tests = [self._draw_test() for _ in range(self.tests_per_episode)]
        self._side, self._sample = self._tests[0]
        self._drawn = True

    def _draw_test(self) -> tuple[Orientation | None, Sample | None]:
        assert self.unit is not None
        side, sample = self._fixed_side, None
        if self.orientation == "random":
            side = SIDES[int(self.np_random.integers(len(SIDES)))]
        if self.uncertain:
            sample = self.uncertainty.draw(self.unit, int(self.np_random.integers(2**63 - 1)))
        return side, sample

    def tested(self, wrap: WrapFormat,
               sample: Sample | None = None) -> tuple[LoadUnit, WrapFormat]:
        """The unit and the wrap as the bench tests them in `sample`, or at their nominal
        values (calibration scaling, relaxation) when it is None."""
        assert self.unit is not None
        if sample is not None:
            return sample.load(self.unit), sample.wrap(wrap)
        return self.unit, self.uncertainty.nominal(wrap)

    # -- Gymnasium API --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._new_unit()
        self._draw_tests()
        self._last = None
        assert self.unit is not None
        return self._obs.copy(), {"load": self.unit.name,
                                  "reference_mass_kg": self.reference_mass_kg,
                                  **self._test_info()}

    def _test_info(self) -> dict[str, Any]:
        return {"orientation": self._side,
                "sample": None if self._sample is None else self._sample.to_json()}

    def _new_unit(self) -> None:
        """The unit of a new episode: the same one (here), a drawn one (WrapBenchRandomEnv)."""

    def decode(self, action: np.ndarray) -> WrapFormat:
        """The wrap an action's program lays on the current unit (clipped; NaN raises)."""
        self._require_unit()
        assert self.program_space is not None
        return self.program_space.decode(action)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        wrap = self.decode(action)
        if not self._drawn:
            raise ResetNeeded("call reset() before step(): an episode starts there, where "
                              "the side tested and the sample are drawn")
        assert self.layout is not None
        runs = [self._run(wrap, side, sample) for side, sample in self._tests]
        judged = min(range(len(runs)), key=lambda i: _severity(runs[i][0].verdict))
        run, unit, simulated = runs[judged]
        self._side, self._sample = self._tests[judged]
        verdict = run.verdict
        used = wrap.material_used_on(self.layout)
        ratio = used.mass_kg / self.reference_mass_kg
        terms = reward_terms(verdict, ratio, self.material_weight)
        self._last = (run.traces[-1], simulated, unit)
        info = {
            "format": wrap.to_json(),
            "verdict": verdict.to_json(),
            "material_used": asdict(used),
            "cycle_time_s": wrap.cycle_time_s,
            "passed": verdict.passed,
            "margin": float(verdict.margin),
            "valid": verdict.valid,
            "material_ratio": ratio,
            "reward_terms": terms,
            "tests_passed": sum(r.verdict.passed for r, _, _ in runs),
            **self._test_info(),
        }
        return self._obs.copy(), float(sum(terms.values())), True, False, info

    def _run(self, wrap: WrapFormat, side: Orientation | None,
             sample: Sample | None) -> tuple[BenchRun, LoadUnit, WrapFormat]:
        """One test of the episode: the run, and the unit and wrap it simulated."""
        unit, simulated = self.tested(wrap, sample)
        sequence = self._sequence if self.levels == "eumos" else [self.target_g]
        return run_levels(unit, sequence, self.settings, orientation=side,
                          stop_at_failure=True, wrap=simulated), unit, simulated

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; make the env with "
                            "render_mode='rgb_array'")
            return None
        self._require_unit()
        assert self.unit is not None
        if self._last is None:
            layout = self.unit.layout(self._side)
            renderer = self._renderer_of(layout)
            pos, rot = rest_state(layout)
            return renderer.frame(pos[PALLET], rot[PALLET], pos[BUNDLES], rot[BUNDLES])
        trace, wrap, tested = self._last
        layout = tested.layout(self._side)
        renderer = self._renderer_of(layout)
        finite = np.flatnonzero([np.isfinite(trace.pallet_pos_m[i]).all()
                                 and np.isfinite(trace.bundle_pos_m[i]).all()
                                 and np.isfinite(trace.bundle_rot[i]).all()
                                 for i in range(len(trace.t_s))])
        index = int(finite[-1]) if len(finite) else 0
        return renderer.trace_frame(trace, index, torn_net(wrap, layout, trace))

    def _renderer_of(self, layout: Layout) -> Renderer:
        """The renderer of `layout`, built anew when the layout changed (another unit, or
        another side along the motion)."""
        if self._renderer is not None and self._renderer.layout != layout:
            self._renderer.close()
            self._renderer = None
        if self._renderer is None:
            self._renderer = Renderer(layout, fitting_camera(layout, *RENDER_SIZE))
        return self._renderer

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()


class WrapBenchRandomEnv(WrapBenchEnv):
    """
    ## Description
    `WrapBenchEnv` on a new load unit at every reset, drawn from `self.np_random`, for policies
    that generalise over units. Everything else (spaces, reward, info, rendering) is as in
    `WrapBenchEnv`; the observation tells the policy which unit it is wrapping.

    ## Starting State
    A unit drawn uniformly: EUR pallet; 1-3 layers; bundle length 0.2-0.4 m, width
    0.15-0.3 m, height 0.2-0.35 m (rounded to mm), mass 4-14 kg (rounded to 0.1 kg); pattern
    columnar or interlocked (a draw that `LoadUnit` rejects, e.g. an interlocked layer that
    would overhang or rest on nothing, is drawn again); static friction of each pair within
    +-15 % of its default value (or of the calibrated one when a calibration is given, taken as
    `Calibration.apply` takes it, with its give), kinetic = 0.8 x static. The pallet stands
    against the sled's stopper, as on an EUMOS bench (a free pallet slides from ~0.45 g on and
    spares the load the rest of the pulse). The same seed gives the same sequence of units.

    ## Arguments
    As `WrapBenchEnv`, without `load`. The material is fixed per env instance.

    ## Version History
    * v3: the bottom wraps' web from a few cm onto the pallet (see `WrapBenchEnv`).
    * v2: at least one bottom and one top wrap (see `WrapBenchEnv`).
    * v1: programs instead of bands, material observed by its card (see `WrapBenchEnv`).
    * v0: initial version.
    """

    draws_units = True

    def __init__(self, **kwargs: Any) -> None:
        if "load" in kwargs:
            raise TypeError("WrapBenchRandomEnv draws its load units; it takes no `load`")
        super().__init__(**kwargs)
        self.base_friction = random_units.base_friction(self.calibration)

    def _new_unit(self) -> None:
        self._set_unit(self.sample_unit(self.np_random))

    def sample_unit(self, rng: np.random.Generator) -> LoadUnit:
        """A load unit drawn from the distribution of the class docstring (with a calibration's
        give, as `WrapBenchEnv` takes it)."""
        unit = random_units.sample_unit(rng, self.base_friction)
        return self.calibration.scale_give(unit) if self.calibration is not None else unit


def reward_terms(verdict: Verdict, material_ratio: float,
                 material_weight: float) -> dict[str, float]:
    """The two reward terms of a tested format (see `WrapBenchEnv`, "Rewards")."""
    margin = float(verdict.margin)
    if verdict.passed:
        term = 1.0 + min(margin, 0.5)
    else:
        term = -1.0 + max(margin, -1.0)
    return {"verdict": term, "material": -material_weight * material_ratio}


def _severity(verdict: Verdict) -> tuple[bool, bool, float]:
    """Orders verdicts worst first: a failure before a pass, a blown-up run before a failure,
    then the smaller margin."""
    return verdict.passed, verdict.valid, float(verdict.margin)


#: Most tests an episode may run (each a full simulation of the levels).
MAX_TESTS_PER_EPISODE = 16


def _tests_per_episode(value: Any, drawn: bool) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not (
            1 <= value <= MAX_TESTS_PER_EPISODE):
        raise InputError("arguments", "tests_per_episode", f"must be a whole number from 1 to "
                         f"{MAX_TESTS_PER_EPISODE} (got {value!r})")
    if value > 1 and not drawn:
        raise InputError("arguments", "tests_per_episode", "more than 1 needs orientation "
                         "'random' or uncertain=True: otherwise every test is the same run")
    return int(value)


@contextmanager
def _as_arguments() -> Iterator[None]:
    """A check shared with the input files names its file: here the argument is gym.make's."""
    try:
        yield
    except InputError as exc:
        raise InputError("arguments", exc.field, exc.message) from None


def _material_weight(value: Any) -> float:
    if not (is_finite_number(value) and value >= 0):
        raise InputError("arguments", "material_weight",
                         f"must be a finite number >= 0 (got {value!r})")
    return float(value)


def _settings(settings: SimSettings | None) -> SimSettings:
    if settings is None:
        return SimSettings()
    if not isinstance(settings, SimSettings):
        raise TypeError(f"settings must be a wrapenv.bench.SimSettings (got {settings!r})")
    return settings


def _one_of(name: str, value: Any, allowed: tuple[Any, ...]) -> Any:
    """An argument that must be one of a few values (an unhashable one is none of them)."""
    if not any(value is a or (isinstance(value, str) and value == a) for a in allowed):
        raise InputError("arguments", name, f"must be one of "
                         f"{', '.join(map(repr, allowed))} (got {value!r})")
    return value


def _level(name: str, value: Any) -> float:
    if not is_real_number(value):
        raise InputError("arguments", name, f"must be a number of g (got {value!r})")
    return float(value)


def _load_unit(load: str | Path | LoadUnit | None) -> LoadUnit:
    if load is None:
        return LoadUnit.from_toml(EXAMPLE_LOAD)
    if isinstance(load, LoadUnit):
        return load
    if isinstance(load, str | Path):
        return LoadUnit.from_toml(load)
    raise TypeError(f"load must be a LOAD.toml path or a LoadUnit (got {load!r})")


def _calibration(calibration: str | Path | Calibration | None) -> Calibration | None:
    if calibration is None or isinstance(calibration, Calibration):
        return calibration
    if isinstance(calibration, str | Path):
        return Calibration.from_json(calibration)
    raise TypeError(f"calibration must be a CAL.json path, a Calibration or None "
                    f"(got {calibration!r})")

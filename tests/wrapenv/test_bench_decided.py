"""A level can stop once its verdict is decided (issue 15, `SimSettings.stop_when_decided`):
searches and training need the verdict, not the rest of a failing run. Such a run must still
fail, and never stop a level that would pass; off by default, so `simulate` keeps full traces.
"""

from __future__ import annotations

import pytest

from tests.wrapenv.conftest import weak_wrap_on_a_slick_unit
from wrapenv.bench import BenchUnit, SimSettings, _Run, run_level
from wrapenv.eumos import FALL_DROP_M, WRAP_TORN, evaluate
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat

EXAMPLE_3 = "examples/pet_3layer_columnar.toml"
DECIDED = SimSettings(stop_when_decided=True)


def example(material: str | None = None) -> tuple[LoadUnit, WrapFormat | None]:
    load = LoadUnit.from_toml(EXAMPLE_3)
    wrap = (WrapFormat.from_toml(f"examples/wrap_{material}_3layer.toml", load.load_height_m)
            if material else None)
    return load, wrap


FAILING = {
    # (load and wrap, level, what decides it)
    "bundles fall": (lambda: example(), 0.5, ("fallen", "elastic displacement")),
    "wrap tears": (weak_wrap_on_a_slick_unit, 0.5, (WRAP_TORN,)),
    "elastic past its limit": (lambda: example("lldpe"), 0.9, ("elastic displacement",)),
}


@pytest.mark.parametrize("case", list(FAILING))
def test_a_decided_level_stops_early_and_still_fails(case):
    make, level, reasons = FAILING[case]
    load, wrap = make()
    early = run_level(load.layout(), PulseProfile(level), DECIDED, wrap)
    full = run_level(load.layout(), PulseProfile(level), SimSettings(), wrap)
    verdict = evaluate(early)
    assert early.stopped_early.startswith(reasons), early.stopped_early
    assert not verdict.passed and verdict.valid
    assert verdict.to_json()["stopped_early"] == early.stopped_early
    assert early.t_s[-1] < full.t_s[-1] - 0.5        # it saved at least half a second
    assert not evaluate(full).passed                   # decided means: the full run fails too


def test_a_passing_level_runs_to_rest_exactly_as_without_the_option():
    load, wrap = example("kraft")
    early = run_level(load.layout(), PulseProfile(0.3), DECIDED, wrap)
    full = run_level(load.layout(), PulseProfile(0.3), SimSettings(), wrap)
    assert early.stopped_early == ""
    assert evaluate(early).passed
    assert early.dropped_m().max() < FALL_DROP_M / 10  # squeezed, on its supports: not fallen
    assert evaluate(early).to_json() == evaluate(full).to_json()
    assert "stopped_early" not in evaluate(full).to_json()


def test_a_bundle_off_its_support_decides_the_level_before_any_displacement():
    """`_Run._decided` on states set by hand, from where the unit stands at t = 0. On the bench
    the elastic limit comes first in every run measured (a bundle slides a tenth of the load's
    height before it can leave its support), so the fall is checked here: an upright bundle
    dropped past `FALL_DROP_M` has slid off onto something lower, is named, and that damage is
    the reason even where its displacement is past the elastic limit too."""
    layout = LoadUnit.from_toml(EXAMPLE_3).layout()
    with BenchUnit(layout, DECIDED) as unit:
        run = _Run(unit.world, layout, PulseProfile(0.5), DECIDED, unit.stick_slip, None, None)
        pos, rot, _, _ = run._state()
    top = len(layout.bundles) - 1                   # a top-layer bundle, the last in the layout
    row = 1 + top                                   # its state row (the pallet's is 0)
    limit_m = run.elastic_limit_m

    def moved(down_m: float = 0.0, along_m: float = 0.0):
        out = pos.copy()
        out[row] += (along_m, 0.0, -down_m)
        return out

    assert run._decided(pos, rot) == ""             # t = 0: the reference
    assert run._decided(moved(down_m=FALL_DROP_M - 0.005), rot) == ""  # the solver's overlap
    name = layout.bundles[top].name
    assert run._decided(moved(down_m=FALL_DROP_M + 0.005), rot) == f"{name} fallen"
    assert run._decided(moved(FALL_DROP_M + 0.005, 2 * limit_m), rot) == f"{name} fallen"
    assert run._decided(moved(along_m=limit_m + 0.005), rot).startswith(
        f"elastic displacement {(limit_m + 0.005) * 1000:.0f} mm past {limit_m * 1000:.0f} mm")
    assert run._decided(moved(along_m=limit_m - 0.005), rot) == ""


def test_a_toppled_bundle_has_fallen_once_its_centre_is_below_where_its_underside_stood():
    """Tipped onto its side, a bundle's centre drops by half the difference of its height and
    width and it still rests on its support: not decided (a topple is judged at the end), nor
    is a drop of 160 mm an elastic displacement past the limit (EUMOS judges the horizontal
    one). Its centre below where its underside stood means it left its support: fallen."""
    layout = LoadUnit.from_toml(EXAMPLE_3).layout()
    with BenchUnit(layout, DECIDED) as unit:
        run = _Run(unit.world, layout, PulseProfile(0.5), DECIDED, unit.stick_slip, None, None)
        pos, rot, _, _ = run._state()
    top = len(layout.bundles) - 1
    row, bundle = 1 + top, layout.bundles[top]
    assert run._decided(pos, rot) == ""             # t = 0: the reference
    on_its_side = rot.copy()
    on_its_side[row] = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]  # 90 degrees about x
    half_height_m = bundle.size_m[2] / 2

    def lowered(by_m: float):
        out = pos.copy()
        out[row, 2] -= by_m
        return out

    tipped_m = half_height_m - bundle.size_m[1] / 2
    assert run._decided(lowered(tipped_m), on_its_side) == ""
    assert run._decided(lowered(half_height_m + 0.005), on_its_side) == f"{bundle.name} fallen"
    assert run._decided(lowered(half_height_m - 0.005), on_its_side) == ""

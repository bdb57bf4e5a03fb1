"""A level skips what cannot change (issue 15): while the sled's acceleration stays constant, a
unit at rest stays as it is, so the run jumps to the next change (`SimSettings.skip_still`).

Each case runs twice, skipping and taken step by step to the end; the verdicts must be the same
and every bundle's permanent and elastic displacement within `TOLERANCE_M`, the noise of a
squeezed stack (a wrapped unit jitters by ~1 mm on the spot, tests/wrapenv/test_wrap_physics.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from wrapenv import bullet
from wrapenv.bench import SimSettings, run_level
from wrapenv.eumos import evaluate
from wrapenv.load import LoadUnit
from wrapenv.profile import G, MeasuredProfile, PulseProfile
from wrapenv.rest import quiet_accel_mps2
from wrapenv.wrap import WrapFormat

TOLERANCE_M = 0.002
EXAMPLE_3 = "examples/pet_3layer_columnar.toml"


def one_bundle(size=(0.28, 0.19, 0.33), mass=9.3, static=0.5, kinetic=0.4, x=0.4):
    """One bundle on a pallet that grips the sled (as in test_bench_mechanics.py)."""
    return LoadUnit.from_dict({
        "pallet": {"preset": "EUR"},
        "bundle": dict(zip(("length_m", "width_m", "height_m"), size, strict=True), mass_kg=mass),
        "stack": {"layers": 1, "pattern": "explicit", "positions": [[x, 0.0]]},
        "friction": {"sled_pallet": {"static": 1.0, "kinetic": 1.0},
                     "pallet_bundle": {"static": static, "kinetic": kinetic}},
    }).layout()


def example_wrap(material: str) -> WrapFormat:
    return WrapFormat.from_toml(f"examples/wrap_{material}_3layer.toml",
                                LoadUnit.from_toml(EXAMPLE_3).load_height_m)


def counted_run(monkeypatch, layout, profile, settings, wrap=None):
    """The trace and how many steps Bullet actually simulated."""
    steps = []
    real = bullet.BulletWorld.step
    monkeypatch.setattr(bullet.BulletWorld, "step", lambda self: (steps.append(1), real(self)))
    trace = run_level(layout, profile, settings, wrap)
    monkeypatch.setattr(bullet.BulletWorld, "step", real)
    return trace, len(steps)


CASES = {
    # slides through the dwell, sticks in the deceleration (closed form: 0.33 m)
    "unwrapped sliding": (one_bundle, PulseProfile(0.6, ramp_s=0.0), None),
    # a 0.10 x 0.40 m bundle above its tipping level w/h = 0.25 g: tips over
    "tipping": (lambda: one_bundle(size=(0.10, 0.2, 0.40), mass=5.0, static=0.9, kinetic=0.8,
                                   x=0.0), PulseProfile(0.2625), None),
    "Kraft-wrapped": (lambda: LoadUnit.from_toml(EXAMPLE_3).layout(), PulseProfile(0.5),
                      "kraft"),
    "LLDPE-wrapped": (lambda: LoadUnit.from_toml(EXAMPLE_3).layout(), PulseProfile(0.5),
                      "lldpe"),
}


@pytest.mark.parametrize("case", list(CASES))
def test_skipping_what_cannot_change_gives_the_verdict_of_the_run_taken_to_the_end(
        case, monkeypatch):
    make_layout, profile, material = CASES[case]
    layout = make_layout()
    wrap = example_wrap(material) if material else None
    skipped, simulated = counted_run(monkeypatch, layout, profile, SimSettings(), wrap)
    full, every_step = counted_run(monkeypatch, layout, profile,
                                   SimSettings(skip_still=False), wrap)
    fast, slow = evaluate(skipped), evaluate(full)
    assert fast.passed == slow.passed
    assert fast.criteria == slow.criteria
    assert fast.damage == slow.damage
    a, b = skipped.bundle_displacement_m(), full.bundle_displacement_m()
    assert np.abs(a[-1] - b[-1]).max() < TOLERANCE_M      # permanent, every bundle
    assert np.abs(a.max(0) - b.max(0)).max() < TOLERANCE_M  # elastic, every bundle
    # what was skipped is the solver's creep at rest: it never adds motion
    assert skipped.pallet_slip_m() < full.pallet_slip_m() + TOLERANCE_M
    # the trace still covers the level, at every step; Bullet simulated far fewer
    assert len(skipped.t_s) == pytest.approx(len(full.t_s), abs=0.1 / (1 / 240))
    assert np.allclose(np.diff(skipped.t_s), 1 / 240)
    assert simulated < 0.8 * every_step


def test_a_unit_that_keeps_moving_is_never_skipped(monkeypatch):
    # the 3-layer example unwrapped at 0.32 g: its front columns topple and fall, nothing rests
    layout = LoadUnit.from_toml(EXAMPLE_3).layout()
    trace, simulated = counted_run(monkeypatch, layout, PulseProfile(0.32), SimSettings())
    settle = round(SimSettings().settle_s * 240)
    assert simulated == settle + len(trace.t_s) - 1


def test_a_still_sled_with_nothing_to_change_ends_as_soon_as_the_unit_rests(monkeypatch):
    layout = one_bundle()
    still = MeasuredProfile(np.array([0.0, 10.0]), np.zeros(2))
    trace, simulated = counted_run(monkeypatch, layout, still, SimSettings())
    assert trace.t_s[-1] >= 10.0                      # the trace covers the profile
    assert simulated < round((0.3 + 0.5) * 240)       # settling and one rest hold, no more


def test_quiet_acceleration_is_the_lowest_friction_or_tipping_level():
    # 3-layer example: a first-layer bundle with the two above it, 0.19 m wide and 0.99 m tall,
    # tips before anything slides (lowest static coefficient 0.40)
    layout = LoadUnit.from_toml(EXAMPLE_3).layout()
    assert quiet_accel_mps2(layout) == pytest.approx(G * 0.19 / 0.99)
    # one bundle: sliding at mu_s = 0.5 comes before tipping at 0.19 / 0.33
    assert quiet_accel_mps2(one_bundle()) == pytest.approx(G * 0.5)


@pytest.mark.parametrize("settings", [SimSettings(), SimSettings(simulate_stop=False)],
                         ids=["default", "ending at the first rest"])
def test_nothing_is_skipped_where_the_deceleration_could_tip_a_body(monkeypatch, settings):
    # a 0.10 x 0.40 m bundle tips at 0.25 g; at a 1.0 g level the sled decelerates at 0.25 g
    layout = one_bundle(size=(0.10, 0.2, 0.40), mass=5.0, static=0.9, kinetic=0.8, x=0.0)
    trace, simulated = counted_run(monkeypatch, layout, PulseProfile(1.0), settings)
    settle = round(SimSettings().settle_s * 240)
    assert simulated == settle + len(trace.t_s) - 1


def test_ending_at_the_first_rest_never_skips_a_later_stretch_that_moves_the_unit():
    """A measured profile still for a second, then 0.6 g for 0.3 s: the bundle (static 0.5,
    kinetic 0.4) rests through the first second, then slides: 0.2 g relative for 0.3 s,
    1.962 x 0.3² / 2 = 88 mm, then from 0.589 m/s at 0.4 g, 0.589² / (2 x 3.924) = 44 mm. A
    run that ends at the first rest after the sled stopped must not take that first rest for
    the end."""
    still_then_pulse = MeasuredProfile(np.array([0.0, 1.0, 1.01, 1.3, 1.31, 2.0]),
                                       np.array([0.0, 0.0, -0.6 * G, -0.6 * G, 0.0, 0.0]))
    slid = [run_level(one_bundle(), still_then_pulse, settings).bundle_displacement_m()[-1].max()
            for settings in (SimSettings(), SimSettings(simulate_stop=False))]
    assert slid[0] == pytest.approx(0.088 + 0.044, rel=0.1)
    assert slid[1] == pytest.approx(slid[0], abs=TOLERANCE_M)


def test_ending_at_the_first_rest_skips_the_stop_and_agrees_on_a_wrapped_pass(monkeypatch):
    # screening (simulate_stop=False): the stop only springs the wrapped unit back elastically
    layout = LoadUnit.from_toml(EXAMPLE_3).layout()
    wrap = example_wrap("kraft")
    exact, exact_steps = counted_run(monkeypatch, layout, PulseProfile(0.5), SimSettings(), wrap)
    first, first_steps = counted_run(monkeypatch, layout, PulseProfile(0.5),
                                     SimSettings(simulate_stop=False), wrap)
    assert evaluate(first).passed and evaluate(exact).passed
    a, b = first.bundle_displacement_m(), exact.bundle_displacement_m()
    assert np.abs(a[-1] - b[-1]).max() < TOLERANCE_M
    assert first_steps <= exact_steps - round(SimSettings().rest_hold_s * 240)
    assert first.t_s[-1] >= PulseProfile(0.5).duration_s  # the trace still covers the pulse

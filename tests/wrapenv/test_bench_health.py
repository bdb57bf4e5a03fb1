"""The bench stays trustworthy over many runs: determinism, no leaks, blow-ups reported."""

from __future__ import annotations

import gc
import json
import math
import os
import platform
import re
import subprocess
import sys

import numpy as np
import pytest

from recommender.cli import main
from tests.conftest import rss_kb
from tests.wrapenv.conftest import kraft_example
from wrapenv import bench, bullet
from wrapenv.bench import BenchUnit, SimSettings, _Run, run_level, run_levels
from wrapenv.config import InputError
from wrapenv.eumos import evaluate
from wrapenv.load import LoadUnit
from wrapenv.profile import G, PulseProfile
from wrapenv.wrap import WrapFormat

SMALL = {
    "pallet": {"preset": "EUR"},
    "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 2, "pattern": "explicit", "positions": [[0.0, 0.0], [0.3, 0.0]]},
}


@pytest.mark.parametrize("field, value", [
    ("timestep_s", -1 / 240), ("timestep_s", math.nan), ("settle_s", -0.1),
    ("max_rest_wait_s", math.inf), ("solver_iterations", 0), ("solver_iterations", 2.5),
    ("max_solver_iterations", True), ("wrapped_contact_erp", 1.5)])
def test_settings_no_run_can_be_made_with_are_refused_naming_the_field(field, value):
    with pytest.raises(InputError, match=f"settings: {field}: must be"):
        SimSettings(**{field: value})


def test_same_inputs_give_identical_json(tmp_path):
    outs = []
    for k in range(2):
        out = tmp_path / f"v{k}.json"
        main(["simulate", "examples/pet_2layer_columnar.toml", "--level", "0.3",
              "--json", str(out)])
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert json.loads(outs[0])["levels"][0]["level_g"] == 0.3


#: A level that turns a last-bit difference into another run: the 2-layer example's top layer
#: sliding off at 0.45 g, unwrapped and Kraft-wrapped (wrap forces reach Bullet too), with
#: reduced-coordinate and rigid boxes (a rigid body's torques reach it as velocities); prints a
#: digest of each trace's positions, which Bullet reports (the trace's rotation matrices are
#: numpy's products of its quaternions, last bits per processor, read only against thresholds).
_CHAOTIC_LEVELS = """
import hashlib
from wrapenv.bench import SimSettings, run_level
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat
load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
for rigid in (False, True):
    for wrap in (None, WrapFormat.from_toml("examples/wrap_kraft_2layer.toml",
                                            load.load_height_m)):
        trace = run_level(load.layout(), PulseProfile(0.45), SimSettings(rigid_boxes=rigid),
                          wrap=wrap)
        print(hashlib.sha256(trace.bundle_pos_m.tobytes()).hexdigest())
"""
#: Another processor, as far as numpy's arithmetic goes: OpenBLAS's SSE3 kernels (every x86-64
#: has them) and numpy's loops without AVX-512 (a no-op where the processor has none).
_ANOTHER_PROCESSOR = {"OPENBLAS_CORETYPE": "Prescott",
                      "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"),
                    reason="OpenBLAS's kernels are named per architecture; these are x86-64's")
def test_processors_that_round_differently_run_the_same_level_identically():
    """Unrounded, OpenBLAS's AVX-512 and AVX2 kernels slid the unwrapped top layer 0.46 and
    0.54 m (wrapenv.bullet.FRICTION_DECIMALS)."""
    digests = []
    for extra in ({}, _ANOTHER_PROCESSOR):
        env = os.environ | extra
        done = subprocess.run([sys.executable, "-c", _CHAOTIC_LEVELS], env=env, check=True,
                              capture_output=True, text=True)
        digests.append(done.stdout.split())
    assert len(digests[0]) == 4
    assert digests[0] == digests[1]


def test_many_runs_close_their_worlds_and_do_not_grow_memory(monkeypatch):
    # A world's finaliser would disconnect a forgotten client too: count the worlds that reach
    # it still connected, so that only an explicit close passes.
    opened, left_open = [], []
    original_init = bullet.BulletWorld.__init__
    monkeypatch.setattr(bullet.BulletWorld, "__init__",
                        lambda self, *a, **k: (opened.append(1), original_init(self, *a, **k))[1])
    monkeypatch.setattr(bullet.BulletWorld, "__del__",
                        lambda self: left_open.append(1) if not self.closed else None)
    layout = LoadUnit.from_dict(SMALL).layout()
    for _ in range(5):  # warm-up: allocator pools, imports
        run_level(layout, PulseProfile(0.2))
    before = rss_kb()
    for _ in range(40):
        run_level(layout, PulseProfile(0.2))
    grown_mb = (rss_kb() - before) / 1024
    gc.collect()
    assert len(opened) == 45 and left_open == []
    assert grown_mb < 20, f"resident memory grew {grown_mb:.1f} MB over 40 runs"


def test_blown_up_simulation_is_invalid_never_a_pass(monkeypatch):
    calls = {"n": 0}
    real = bullet.BulletWorld.state

    def exploding(self, indices):
        pos, quat, lin, ang = real(self, indices)
        calls["n"] += 1
        if calls["n"] > 100:
            lin = lin + 1e3  # energy from nowhere
        return pos, quat, lin, ang

    monkeypatch.setattr(bullet.BulletWorld, "state", exploding)
    run = run_levels(LoadUnit.from_dict(SMALL), [0.2])
    level = run.verdict.levels[0]
    assert not run.verdict.valid
    assert not level.passed
    assert "blow-up" in level.invalid_reason
    assert run.verdict.to_json()["highest_passed_g"] is None


def test_a_unit_flung_apart_while_it_is_wrapped_is_invalid_not_a_failure():
    """Bundles of 0.1 kg (5.7 kg/m³, as light as goods come) under the Kraft default's 800 N:
    the squeeze flings them off the pallet while the wrap is laid, before the sled moves, and
    the level is no test. Judged from where they landed, such a level was an energy blow-up
    "during the run" here, and with 1 g bundles (now refused as a load) a valid failure, every
    bundle fallen at t = 0. It says what happened, and when."""
    load = LoadUnit.from_dict({
        "name": "0.1 kg bundles", "pallet": {"preset": "EUR"},
        "bundle": {"length_m": 0.28, "width_m": 0.19, "height_m": 0.33, "mass_kg": 0.1},
        "stack": {"layers": 2, "pattern": "columnar"}})
    wrap = WrapFormat.from_toml("examples/program_kraft_default.toml", load.load_height_m)
    level = run_levels(load, [0.3], wrap=wrap).verdict.levels[0]
    assert not level.valid and not level.passed
    said = re.fullmatch(r"the unit came apart before the sled moved \((\S+) moved (\d+) mm "
                        r"while it was stacked and wrapped\)", level.invalid_reason)
    assert said and said[1] in {b.name for b in load.layout().bundles}
    assert int(said[2]) > 1200                        # farther than the EUR pallet is long


def test_a_unit_that_slides_off_the_sled_fails_and_is_no_blow_up():
    """A pallet on an icy deck (kinetic 0.04) at 0.8 g lags the sled by (a - mu g) T^2 / 2 =
    0.93 m over the 0.5 s dwell, then slides on at 3.73 m/s against mu g plus the sled's
    braking (a quarter of the level): 3.73^2 / (2 x 2.35) = 2.96 m more. 3.9 m in all takes
    its centre past the deck's edge, 2 m beyond the pallet's 0.6 m half-length: it falls off
    the sled. That is a failed level, not an unphysical run (a body falling past the deck
    would reach the blow-up speed limit)."""
    a, mu_g, dwell = 0.8 * 9.81, 0.04 * 9.81, 0.5
    lag = (a - mu_g) * dwell**2 / 2
    speed = (a - mu_g) * dwell
    assert lag + speed**2 / (2 * (mu_g + a / 4)) > 2.0 + 0.6
    icy = dict(SMALL, friction={"sled_pallet": {"static": 0.05, "kinetic": 0.04}})
    run = run_levels(LoadUnit.from_dict(icy), [0.8])
    level = run.verdict.levels[0]
    assert run.verdict.valid and level.valid
    assert not level.passed
    assert level.stopped_early == "pallet fell off the sled"
    assert run.verdict.to_json()["highest_passed_g"] is None


def test_non_finite_state_is_invalid(monkeypatch):
    """NaN from the start: the unit is judged to have come apart before the sled moved."""
    real = bullet.BulletWorld.poses

    def nan_poses(self, indices):
        pos, quat = real(self, indices)
        return pos * np.nan, quat

    monkeypatch.setattr(bullet.BulletWorld, "poses", nan_poses)
    trace = run_level(LoadUnit.from_dict(SMALL).layout(), PulseProfile(0.2))
    assert not trace.valid
    assert not evaluate(trace).passed


def _from_call(n: int, monkeypatch, method: str, change, until: float = math.inf) -> None:
    """BulletWorld.`method` answers as Bullet does, then `change`d from its `n`-th call on
    (before its `until`-th): the level is under way (the settled state, the first call, was
    sound)."""
    real, calls = getattr(bullet.BulletWorld, method), {"n": 0}

    def later(self, *args):
        calls["n"] += 1
        answer = real(self, *args)
        return change(answer) if n <= calls["n"] < until else answer

    monkeypatch.setattr(bullet.BulletWorld, method, later)


def test_a_state_turned_non_finite_during_the_level_is_invalid(monkeypatch):
    _from_call(100, monkeypatch, "state", lambda s: (s[0] * np.nan, *s[1:]))
    trace = run_level(LoadUnit.from_dict(SMALL).layout(), PulseProfile(0.2))
    assert (trace.valid, trace.invalid_reason) == (False, "non-finite state")
    assert not evaluate(trace).passed


def test_bodies_the_solver_let_sink_into_each_other_make_the_level_invalid(monkeypatch):
    """Deeper than `PENETRATION_LIMIT_M` for `PENETRATION_HOLD_S` the solver has lost the
    contact: whatever the figures say, the run is no test. The depth, a query over every
    contact, is read every 24 steps, and every step while it stands past the limit: past it
    from the reading at step 24, still past it at step 48 (0.1 s later), which ends the run."""
    _from_call(2, monkeypatch, "max_penetration_m", lambda depth: 0.05)
    every_step = SimSettings(skip_still=False)
    trace = run_level(LoadUnit.from_dict(SMALL).layout(), PulseProfile(0.2), every_step)
    assert (trace.valid, trace.invalid_reason) == (False,
                                                   "bodies interpenetrate by 50 mm for 0.1 s")
    assert len(trace.t_s) == 49 and trace.t_s[-1] == pytest.approx(48 / 240)
    assert not evaluate(trace).passed


def _deep_at_readings(monkeypatch, readings: range) -> None:
    """BulletWorld.max_penetration_m answers 50 mm at the given readings (counted from 1),
    as Bullet does at the others."""
    _from_call(readings.start, monkeypatch, "max_penetration_m", lambda depth: 0.05,
               until=readings.stop)


def test_an_overlap_pushed_out_within_the_hold_is_an_impact_not_a_lost_contact(monkeypatch):
    # past the limit at the readings of steps 24 to 27, then as Bullet says: what a body
    # driven in by an impact and pushed out by the solver looks like
    layout = LoadUnit.from_dict(SMALL).layout()
    clean = run_level(layout, PulseProfile(0.2))
    _deep_at_readings(monkeypatch, range(2, 6))
    trace = run_level(layout, PulseProfile(0.2))
    assert trace.valid and trace.invalid_reason == ""
    np.testing.assert_array_equal(trace.bundle_pos_m, clean.bundle_pos_m)


def test_an_overlap_still_past_the_limit_when_the_level_comes_to_rest_is_a_lost_contact(
        monkeypatch):
    # at rest no impact is being pushed out: the overlap counts however briefly it was read
    layout, every_step = LoadUnit.from_dict(SMALL).layout(), SimSettings(skip_still=False)
    steps = len(run_level(layout, PulseProfile(0.2), every_step).t_s) - 1
    assert steps % bench.PENETRATION_READ_STEPS, "the last step must fall between readings"
    first_deep = steps // bench.PENETRATION_READ_STEPS + 1  # the last regular reading's number
    _deep_at_readings(monkeypatch, range(first_deep, first_deep + 1000))
    trace = run_level(layout, PulseProfile(0.2), every_step)
    assert len(trace.t_s) - 1 == steps and not trace.not_at_rest
    assert (trace.valid, trace.invalid_reason) == (False, "bodies interpenetrate by 50 mm at rest")


def test_a_bundle_falling_onto_the_deck_is_a_failed_level_not_an_invalid_one(monkeypatch):
    """A top-layer bundle of the 3-layer example falls about a metre onto the sled's deck at
    0.6 g: the solver lets it 23 mm into the deck and pushes it out within a few steps. Read
    at every step, that impact made the level invalid under a limit on one step's overlap
    (the level then was invalid or not by whether the reading every 24 steps fell on it)."""
    monkeypatch.setattr(bench, "PENETRATION_READ_STEPS", 1)
    depths: list[float] = []
    real = bullet.BulletWorld.max_penetration_m

    def recorded(self):
        depths.append(real(self))
        return depths[-1]

    monkeypatch.setattr(bullet.BulletWorld, "max_penetration_m", recorded)
    load = LoadUnit.from_toml("examples/pet_3layer_columnar.toml")
    trace = run_level(load.layout(), PulseProfile(0.6))
    assert trace.valid, trace.invalid_reason
    deepest = int(np.argmax(depths))
    assert depths[deepest] > bench.PENETRATION_LIMIT_M  # the impact, read
    assert max(depths[deepest + 6:]) < bench.PENETRATION_LIMIT_M  # pushed out in a few steps
    verdict = evaluate(trace)
    assert not verdict.passed and any("fallen" in d for d in verdict.damage)


@pytest.mark.parametrize("rigid", [False, True], ids=["reduced", "rigid"])
def test_velocities_from_one_step_of_poses_are_bullets_own(monkeypatch, rigid):
    # BulletWorld.state derives velocities from the poses of consecutive steps (one pybullet
    # call per body instead of two); they must be what Bullet reports, through a wrapped level
    errors = []
    real = bullet.BulletWorld.state

    def checked(self, indices):
        pos, quat, lin, ang = real(self, indices)
        own_lin, own_ang = self.velocities(indices)
        errors.append(max(np.abs(lin - own_lin).max(), np.abs(ang - own_ang).max()))
        return pos, quat, lin, ang

    monkeypatch.setattr(bullet.BulletWorld, "state", checked)
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    wrap = WrapFormat.from_toml("examples/wrap_kraft_2layer.toml", load.load_height_m)
    run_level(load.layout(), PulseProfile(0.5), SimSettings(rigid_boxes=rigid), wrap=wrap)
    assert len(errors) > 200
    assert max(errors) < 1e-9


def test_a_body_faster_than_the_sled_s_whole_change_of_speed_plus_a_fall_is_a_blow_up():
    """No body can move relative to the sled faster than the sled's whole change of speed plus
    the speed of a fall from the load's top, with 1 m/s to spare: the 0.5 g pulse (ramp 0.05 s,
    dwell 0.5 s, braking at a quarter of the level, its ramp down as steep as the ramp up)
    brings the sled to a(r/2 + dwell) + (a - d) r_down/2 = 2.690 m/s by hand."""
    a, d, r = 0.5 * G, 0.125 * G, 0.05
    sled_mps = a * (r / 2 + 0.5) + (a - d) * (r * (a + d) / a) / 2
    layout = LoadUnit.from_toml("examples/pet_3layer_columnar.toml").layout()
    limit = sled_mps + math.sqrt(2 * G * layout.load_height_m) + 1.0
    with BenchUnit(layout) as unit:
        run = _Run(unit.world, layout, PulseProfile(0.5), SimSettings(), unit.stick_slip, None,
                   None)
        pos, _, vel, _ = run._state()
        assert run.speed_limit == pytest.approx(limit, abs=0.01)
        vel[-1] = (limit - 0.02, 0.0, 0.0)
        run._check(pos, vel, step=1)
        assert run.invalid == ""
        vel[-1] = (0.0, limit + 0.02, 0.0)
        run._check(pos, vel, step=1)
    assert run.invalid == f"a body exceeded {limit:.1f} m/s (energy blow-up)"


def test_a_wrapped_run_left_with_bodies_inside_each_other_is_solved_again_up_to_the_most(
        monkeypatch):
    """An overlap that stands past the limit in a wrapped unit is a squeeze the solver did not
    solve, as a creeping stack is: the run is made again with twice the iterations (50, 100,
    200), and an overlap still there at the most leaves the run invalid, each count said."""
    load, wrap = kraft_example()
    _from_call(2, monkeypatch, "max_penetration_m", lambda depth: 0.05)
    heard: list[int] = []
    run = run_levels(load, [0.2], wrap=wrap, on_rerun=heard.append)
    inside = "left bodies inside each other"
    assert heard == [100, 200] and run.unsolved_at == ((50, inside), (100, inside))
    assert run.solver_iterations == 200 and not run.verdict.valid
    assert run.traces[0].unsolved == inside


def test_a_wrapped_run_that_blew_up_is_solved_again_a_bare_one_is_not(monkeypatch):
    """A wrapped unit's energy blow-up is its squeeze unsolved too, and is made again; a bare
    unit is solved with `solver_iterations`, which a rerun does not raise, so its blow-up or
    overlap stays invalid from its first run."""
    load, wrap = kraft_example()
    heard: list[int] = []
    with monkeypatch.context() as patched:
        _from_call(100, patched, "state", lambda s: (s[0], s[1], s[2] + 100.0, s[3]))
        run = run_levels(load, [0.2], wrap=wrap, on_rerun=heard.append)
    assert "energy blow-up" in run.traces[0].invalid_reason
    assert heard == [100, 200] and run.unsolved_at == ((50, "blew up"), (100, "blew up"))
    heard.clear()
    with monkeypatch.context() as patched:
        _from_call(100, patched, "state", lambda s: (s[0], s[1], s[2] + 100.0, s[3]))
        bare_blown = run_levels(load, [0.2], on_rerun=heard.append)
    _from_call(2, monkeypatch, "max_penetration_m", lambda depth: 0.05)
    bare = run_levels(load, [0.2], on_rerun=heard.append)
    assert bare_blown.traces[0].unsolved == "blew up" and not bare_blown.verdict.valid
    assert bare.traces[0].unsolved == "left bodies inside each other" and not bare.verdict.valid
    assert heard == [] and bare_blown.unsolved_at == bare.unsolved_at == ()

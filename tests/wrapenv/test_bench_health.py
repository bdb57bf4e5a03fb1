"""The bench stays trustworthy over many runs: determinism, no leaks, blow-ups reported."""

from __future__ import annotations

import json

import numpy as np

from recommender.cli import main
from wrapenv import bullet
from wrapenv.bench import run_level, run_levels
from wrapenv.eumos import evaluate
from wrapenv.load import LoadUnit
from wrapenv.profile import PulseProfile
from wrapenv.wrap import WrapFormat

SMALL = {
    "pallet": {"preset": "EUR"},
    "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 2, "pattern": "explicit", "positions": [[0.0, 0.0], [0.3, 0.0]]},
}


def test_same_inputs_give_identical_json(tmp_path):
    outs = []
    for k in range(2):
        out = tmp_path / f"v{k}.json"
        main(["simulate", "examples/pet_2layer_columnar.toml", "--level", "0.3",
              "--json", str(out)])
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert json.loads(outs[0])["levels"][0]["level_g"] == 0.3


def _rss_kb() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4


def test_many_runs_close_their_worlds_and_do_not_grow_memory(monkeypatch):
    closed = []
    original = bullet.BulletWorld.close
    monkeypatch.setattr(bullet.BulletWorld, "close",
                        lambda self: (closed.append(1), original(self))[1])
    layout = LoadUnit.from_dict(SMALL).layout()
    for _ in range(5):  # warm-up: allocator pools, imports
        run_level(layout, PulseProfile(0.2))
    before = _rss_kb()
    for _ in range(40):
        run_level(layout, PulseProfile(0.2))
    grown_mb = (_rss_kb() - before) / 1024
    assert len(closed) >= 45
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


def test_non_finite_state_is_invalid(monkeypatch):
    real = bullet.BulletWorld.poses

    def nan_poses(self, indices):
        pos, quat = real(self, indices)
        return pos * np.nan, quat

    monkeypatch.setattr(bullet.BulletWorld, "poses", nan_poses)
    trace = run_level(LoadUnit.from_dict(SMALL).layout(), PulseProfile(0.2))
    assert not trace.valid
    assert not evaluate(trace).passed


def test_velocities_from_one_step_of_poses_are_bullets_own(monkeypatch):
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
    run_level(load.layout(), PulseProfile(0.5), wrap=wrap)
    assert len(errors) > 200
    assert max(errors) < 1e-9

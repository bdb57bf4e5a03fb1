"""The robust CMA-ES search: uncertain samples, objective, checkpoint and resume, and the
`recommend` command's contract on a load that simulates in a fraction of a second."""

from __future__ import annotations

import json
import pickle
import tomllib
from pathlib import Path

import numpy as np
import pytest

from recommender.cli import EXAMPLE_LOAD, main
from recommender.search import (
    MASS_SPREAD,
    Problem,
    RobustSearch,
    SearchSettings,
    SearchState,
    _objective,
)
from wrapenv.calibrated import Calibration
from wrapenv.config import InputError
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

#: One layer of four PET bundles: each bench run takes a fraction of a second.
SMALL = {
    "name": "small",
    "pallet": {"preset": "EUR"},
    "bundle": {"preset": "PET6x1.5L"},
    "stack": {"layers": 2, "pattern": "explicit",
              "positions": [[-0.15, -0.1], [0.15, -0.1], [-0.15, 0.1], [0.15, 0.1]]},
    "fixture": {"pallet_stopper": True},
}
FAST = SearchSettings(target_g=0.5, samples=2, popsize=4, max_candidates=8, workers=2)


@pytest.fixture
def small_load() -> LoadUnit:
    return LoadUnit.from_dict(SMALL)


def test_samples_stay_within_the_uncertainty_and_repeat_under_a_seed(small_load):
    problem = Problem.build(small_load, FAST)
    nominal = small_load.friction
    samples = [problem.sample_load(seed) for seed in range(50)]
    assert problem.sample_load(7) == problem.sample_load(7)
    for s in samples:
        for name in ("sled_pallet", "pallet_bundle", "bundle_bundle"):
            pair = s.friction.pair(name)
            assert pair.kinetic <= pair.static
            assert abs(pair.static - nominal.pair(name).static) < 5 * 0.03
        assert abs(s.bundle.mass_kg / small_load.bundle.mass_kg - 1) <= MASS_SPREAD
    assert len({s.friction.pallet_bundle.static for s in samples}) == 50


def test_calibrated_std_widens_the_samples(small_load):
    cal = Calibration.from_dict({"friction": {"pallet_bundle": {
        "static": 0.3, "kinetic": 0.25, "static_std": 0.1, "kinetic_std": 0.08}}})
    wide = Problem.build(small_load, FAST, cal)
    narrow = Problem.build(small_load, FAST)
    spread = [np.std([p.sample_load(s).friction.pallet_bundle.static for s in range(200)])
              for p in (wide, narrow)]
    assert spread[0] > 2 * spread[1]


def test_any_failing_candidate_scores_worse_than_any_passing_one(small_load):
    problem = Problem.build(small_load, FAST)
    heaviest = problem.wrap(np.ones(8))
    lightest = problem.wrap(-np.ones(8))
    layout = small_load.layout()
    passing = _objective(problem, heaviest, heaviest.material_used_on(layout).mass_kg, [0.3])
    failing = _objective(problem, lightest, lightest.material_used_on(layout).mass_kg, [-0.01])
    assert failing > passing


def test_target_above_the_bench_is_a_clear_error(small_load):
    with pytest.raises(InputError, match="10 m/s"):
        Problem.build(small_load, SearchSettings(target_g=1.2))


def test_search_finds_a_robust_pass_and_resumes_from_its_checkpoint(small_load, tmp_path):
    ckpt = tmp_path / "search.ckpt"
    problem = Problem.build(small_load, FAST)
    search = RobustSearch(problem, ckpt)
    state = search.start()
    one = SearchSettings(**{**FAST.__dict__, "max_candidates": 4})
    RobustSearch(Problem.build(small_load, one), ckpt).run(state)  # "interrupted" after 1 gen
    saved = pickle.loads(ckpt.read_bytes())
    assert isinstance(saved, SearchState) and saved.generation == 1
    resumed = search.run(search.resume())
    assert resumed.generation >= 2 and len(resumed.history) >= 8
    assert resumed.history[:4] == saved.history[:4]   # nothing of the first generation lost
    best = resumed.best(FAST.margin_goal)
    assert best is not None and best.robust_pass


def test_resume_without_a_checkpoint_is_a_clear_error(small_load, tmp_path):
    search = RobustSearch(Problem.build(small_load, FAST), tmp_path / "none.ckpt")
    with pytest.raises(InputError, match="no checkpoint"):
        search.resume()


def test_recommend_writes_the_contract_json_and_a_wrap_simulate_accepts(load_file, tmp_path,
                                                                        capsys):
    load = load_file(base=SMALL)
    out, wrap = tmp_path / "rec.json", tmp_path / "rec_wrap.toml"
    code = main(["recommend", str(load), "--budget", "8", "--samples", "2", "--workers", "2",
                 "--json", str(out), "--wrap-out", str(wrap),
                 "--checkpoint", str(tmp_path / "s.ckpt")])
    text = capsys.readouterr().out
    assert code == 0
    assert "recommended wrap" in text and "material used" in text and "bottom wraps" in text
    result = json.loads(out.read_text())
    assert {"format", "material_used", "verdict", "robust_pass_rate", "evaluations",
            "method"} <= set(result)
    assert result["method"] == "cmaes" and 0 <= result["robust_pass_rate"] <= 1
    assert result["verdict"]["highest_passed_g"] == pytest.approx(0.5)
    assert WrapFormat.from_toml(wrap).to_dict() == result["format"]
    assert not (tmp_path / "s.ckpt").exists(), "the checkpoint goes when the search ends"
    assert main(["simulate", str(load), "--wrap", str(wrap), "--level", "0.5"]) == 0


@pytest.mark.parametrize("argv, field", [
    (["--material", "cotton"], "--material"),
    (["--target", "1.5"], "--target"),
    (["--samples", "0"], "--samples"),
    (["--workers", "0"], "--workers"),
    (["--margin", "1.5"], "--margin"),
    (["--resume"], "--resume"),
])
def test_bad_recommend_arguments_exit_2_with_one_line(argv, field, load_file, tmp_path, capsys):
    load = load_file(base=SMALL)
    code = main(["recommend", str(load), *argv, "--checkpoint", str(tmp_path / "none.ckpt"),
                 "--json", str(tmp_path / "out.json")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and field in err
    assert not (tmp_path / "out.json").exists()


def test_ppo_method_answers_from_a_policy_and_verifies_it(load_file, tmp_path, capsys):
    import gymnasium as gym
    from stable_baselines3 import PPO

    load = load_file(base=SMALL)
    env = gym.make("wrapenv/WrapBench-v0", load=str(load))
    PPO("MlpPolicy", env, n_steps=64, batch_size=32, device="cpu", seed=0).save(tmp_path / "p")
    env.close()
    out = tmp_path / "ppo.json"
    code = main(["recommend", str(load), "--method", "ppo", "--policy", str(tmp_path / "p.zip"),
                 "--samples", "2", "--workers", "2", "--json", str(out)])
    assert "recommended wrap" in capsys.readouterr().out
    result = json.loads(out.read_text())
    assert result["method"] == "ppo"
    assert code == (0 if result["verdict"]["levels"][-1]["passed"] else 1)


@pytest.mark.parametrize("argv, field", [
    (["recommend", "--method", "ppo"], "--policy"),
    (["train", "--out", "OUT", "--timesteps", "0"], "--timesteps"),
    (["train", "--out", "OUT", "--material", "cotton"], "--material"),
    (["train", "--out", "OUT", "--target", "2.0"], "--target"),
])
def test_bad_policy_arguments_exit_2_with_one_line(argv, field, tmp_path, capsys):
    argv = [str(tmp_path / "out") if a == "OUT" else a for a in argv]
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and field in err


def test_the_bundled_example_is_package_data_and_the_readme_example():
    """`recommend` without LOAD reads a file inside the package, so a wheel install finds it;
    it is the repository's examples/pet_2layer_columnar.toml."""
    root = Path(__file__).resolve().parents[2]
    assert EXAMPLE_LOAD.parent == root / "recommender" / "data"
    assert EXAMPLE_LOAD.read_bytes() == (root / "examples/pet_2layer_columnar.toml").read_bytes()
    pyproject = tomllib.loads((root / "pyproject.toml").read_text())
    assert "data/*.toml" in pyproject["tool"]["setuptools"]["package-data"]["recommender"]

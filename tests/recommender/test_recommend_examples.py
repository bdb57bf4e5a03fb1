"""`wrapbench recommend` on the example loads (issue 4, "Must show"). Minutes per load: marked
slow, run with ``python -m pytest -m slow tests/recommender/test_recommend_examples.py``.

The recommended format passes the target when re-simulated from its `--wrap-out` file; a format
with one layer less in any band, or every tension 20 % lower, loses margin or fails; a lower
target never needs more material.
"""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from recommender.cli import main
from wrapenv.bench import run_levels
from wrapenv.load import LoadUnit
from wrapenv.profile import eumos_levels
from wrapenv.wrap import WrapFormat

pytestmark = pytest.mark.slow

EXAMPLES = ["examples/pet_2layer_columnar.toml", "examples/pet_3layer_columnar.toml"]
#: Margins closer than this are solver noise (~1.5 mm of elastic displacement on an 80 mm limit).
MARGIN_NOISE = 0.02
BUDGET = ["--budget", "24", "--samples", "2"]


def recommend(load: str, tmp_path, target: float) -> tuple[dict, WrapFormat]:
    out, wrap = tmp_path / f"rec_{target}.json", tmp_path / f"rec_{target}.toml"
    code = main(["recommend", load, "--target", str(target), *BUDGET, "--json", str(out),
                 "--wrap-out", str(wrap), "--checkpoint", str(tmp_path / "search.ckpt")])
    assert code == 0
    height = LoadUnit.from_toml(load).load_height_m
    return json.loads(out.read_text()), WrapFormat.from_toml(wrap, height)


def margin(load: LoadUnit, wrap: WrapFormat, target: float) -> float:
    verdict = run_levels(load, eumos_levels(target), stop_at_failure=True, wrap=wrap).verdict
    return verdict.margin if verdict.passed else -1.0


@pytest.mark.parametrize("load_path", EXAMPLES)
def test_recommended_format_passes_and_has_no_material_to_spare(load_path, tmp_path):
    result, wrap = recommend(load_path, tmp_path, 0.5)
    load = LoadUnit.from_toml(load_path)
    assert main(["simulate", load_path, "--wrap", str(tmp_path / "rec_0.5.toml"),
                 "--target", "0.5"]) == 0
    assert result["verdict"]["levels"][-1]["passed"] and result["robust_pass_rate"] >= 0.75
    base = margin(load, wrap, 0.5)
    for i, band in enumerate(wrap.bands):
        fewer = [*wrap.bands[:i], *([replace(band, layers=band.layers - 1)]
                                    if band.layers > 1 else []), *wrap.bands[i + 1:]]
        assert margin(load, wrap.with_bands(fewer), 0.5) <= base + MARGIN_NOISE, band
    looser = wrap.with_bands([replace(b, tension_n=0.8 * b.tension_n) for b in wrap.bands])
    assert margin(load, looser, 0.5) <= base + MARGIN_NOISE


def test_a_lower_target_never_needs_more_material(tmp_path):
    low, _ = recommend(EXAMPLES[0], tmp_path, 0.3)
    high, _ = recommend(EXAMPLES[0], tmp_path, 0.5)
    assert low["material_used"]["mass_kg"] <= high["material_used"]["mass_kg"]


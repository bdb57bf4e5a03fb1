"""`simulate --tension-map OUT.png` and `wrap.critical` in its JSON (issue 12): the map is
checked before any work and drawn after; bad input exits 2 with one line, nothing written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from recommender import report
from tests.cli import one_line, run
from tests.conftest import TINY_LOAD
from tests.wrapenv.conftest import weak_wrap_on_a_slick_unit
from wrapenv.bench import run_levels

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_the_default_kraft_program_maps_the_tiny_unit_and_does_not_tear_it(load_file, tmp_path,
                                                                           capsys):
    """800 N of Kraft squeezes the two bundles together (they start 12 cm apart): that once
    tore the top ring through a hull that crossed itself; it must not."""
    load = load_file(base=TINY_LOAD)
    out_json, out_png = tmp_path / "verdict.json", tmp_path / "map.png"
    code = run(["simulate", str(load), "--wrap", str(EXAMPLES / "program_kraft_default.toml"),
                "--level", "0.3", "--json", str(out_json), "--tension-map", str(out_png)])
    assert code == 0, capsys.readouterr()
    assert out_png.read_bytes().startswith(PNG_MAGIC)
    wrap = json.loads(out_json.read_text())["levels"][0]["wrap"]
    assert wrap["torn"] is False and wrap["opened"] is False
    assert wrap["critical"][0]["utilisation"] == wrap["peak_utilisation"] < 0.5
    assert all({"height_m", "where", "utilisation", "t_s"} <= set(c) for c in wrap["critical"])


@pytest.mark.parametrize("argv, field", [
    (["--tension-map", "{tmp}/map.png"], "--tension-map"),                  # no --wrap
    (["--wrap", "{wrap}", "--tension-map", "{tmp}/no/map.png"], "--tension-map"),  # no folder
])
def test_a_map_that_cannot_be_made_exits_2_before_any_work(argv, field, load_file, tmp_path,
                                                           capsys):
    load = load_file(base=TINY_LOAD)
    wrap = EXAMPLES / "program_kraft_default.toml"
    args = [a.format(tmp=tmp_path, wrap=wrap) for a in argv]
    code = run(["simulate", str(load), "--level", "0.3", "--json", str(tmp_path / "v.json"),
                *args])
    out, err = capsys.readouterr()
    assert code == 2 and f": {field}: " in one_line(err)
    assert out == "" and not (tmp_path / "v.json").exists() and not (tmp_path / "map.png").exists()


def test_a_give_out_of_range_exits_2_naming_the_field(load_file, tmp_path, capsys):
    load = load_file({"bundle.corner_stiffness_n_per_m2": 5e9})
    code = run(["simulate", str(load), "--level", "0.2", "--json", str(tmp_path / "v.json")])
    line = one_line(capsys.readouterr().err)
    assert code == 2 and str(load) in line and ": bundle.corner_stiffness_n_per_m2: " in line
    assert not (tmp_path / "v.json").exists()


def test_a_wrap_card_field_out_of_range_exits_2_naming_the_field(load_file, wrap_file,
                                                                 tmp_path, capsys):
    card = {"grammage_kg_m2": 0.09, "stiffness_n_per_m": 4e5, "yield_strain": 0.008,
            "break_strain": 0.07, "kind": "paper", "interlayer_friction": 3.0}
    wrap = wrap_file({"material": card})
    code = run(["simulate", str(load_file()), "--wrap", str(wrap), "--level", "0.2"])
    line = one_line(capsys.readouterr().err)
    assert code == 2 and ": material.interlayer_friction: " in line


def test_a_torn_wrap_s_map_marks_every_torn_place(monkeypatch):
    """A web that breaks at 0.4 % strain round the 2-layer example on a slippery deck tears at
    0.5 g (tests/wrapenv/test_wrap_physics.py): the map crosses out each place that tore, and
    the glued seam that let go."""
    slick, weak = weak_wrap_on_a_slick_unit()
    run = run_levels(slick, [0.5], wrap=weak)
    places = run.traces[0].wrap.places
    failed = [(p.where, p.height_m) for p in places
              if p.torn or (p.opened and p.element == "seam")]
    assert any(p.torn for p in places), "the case is chosen to tear"
    marked: list[tuple[str, float]] = []
    real = report._mark_failure
    monkeypatch.setattr(report, "_mark_failure",
                        lambda ax, p: (marked.append((p.where, p.height_m)), real(ax, p)))
    png = report.plot_tension_map(run, slick.layout())
    assert png.startswith(PNG_MAGIC)
    assert sorted(marked) == sorted(failed)

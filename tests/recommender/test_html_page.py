"""The one-page report's HTML (recommender/html_page.py), without a browser: every user string
escaped and bounded, each EUMOS criterion's figure against its limit, the load and the program as
entered, figures inlined as data: URIs, the video beside the page, and what recommend adds."""

from __future__ import annotations

import base64
import re
from dataclasses import replace
from html.parser import HTMLParser
from importlib import metadata
from typing import Any

import cv2
import numpy as np

from recommender.html_page import Figure, OrientationRun, Page, Robustness, SearchFacts, render
from recommender.search import Trial
from wrapenv.bench import BenchRun
from wrapenv.eumos import LevelVerdict, Verdict
from wrapenv.load import LoadUnit
from wrapenv.uncertainty import PassProbability
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_report import Place, WrapReport

#: A name that would break the page, its title or a plot if it were written raw.
HOSTILE = '<script>alert("x")</script><img src=x onerror=alert(1)> & $\\frac{$ \x1b[31m'
#: Two layers of PET bundles on a EUR pallet: load height 0.144 + 2 x 0.33 = 0.804 m, so the
#: EUMOS limits are 10 % = 80.4 mm elastic and 5 % = 40.2 mm permanent.
LOAD = {"name": HOSTILE, "pallet": {"preset": "EUR"}, "bundle": {"preset": "PET6x1.5L"},
        "stack": {"layers": 2, "pattern": "columnar"}}
CRITERIA_OK = {"permanent_5pct": True, "low20_4cm": True, "elastic_10pct": True,
               "no_damage": True}


def png(value: int) -> bytes:
    return cv2.imencode(".png", np.full((20, 30, 3), value, np.uint8))[1].tobytes()


def level(level_g: float, elastic_m: float, permanent_m: float, low20_m: float,
          criteria: dict[str, bool] = CRITERIA_OK, damage: tuple[str, ...] = ()) -> LevelVerdict:
    h = 0.804
    passed = all(criteria.values())
    return LevelVerdict(level_g, passed, True, elastic_m, 100 * elastic_m / h, permanent_m,
                        100 * permanent_m / h, low20_m, 0.001, damage, criteria, ())


def page(robustness: Robustness | None = None, **changes: Any) -> Page:
    """A page of two levels, 0.3 g passing and 0.4 g failing the elastic criterion."""
    load = LoadUnit.from_dict(LOAD)
    failing = {**CRITERIA_OK, "elastic_10pct": False, "no_damage": False}
    run = BenchRun(Verdict(0.804, (level(0.3, 0.0118, 0.0089, 0.0088),
                                   level(0.4, 0.1234, 0.0350, 0.0390, failing,
                                         ("L2C1R1 toppled",)))), (), 50)
    wrap = WrapFormat.from_dict(
        {"material": {"name": "<b>paper</b>", "grammage_kg_m2": 0.09,
                      "stiffness_n_per_m": 40000.0, "yield_strain": 0.02, "break_strain": 0.06},
         "web_width_m": 0.5,
         "program": {"bottom_wraps": 3, "bottom_tension_n": 400.0, "up_overlap": 0.5,
                     "middle_tension_n": 250.0, "top_wraps": 2, "top_tension_n": 300.0}},
        "wrap.toml", 0.804)
    fields: dict[str, Any] = {
        "heading": "Bench test report", "load": load,
        "tested": (OrientationRun(None, load.layout(), run),), "wrap": wrap,
        "hours_since_wrapping": 16.0,
        "inputs": (("load unit", "dir/<load>.toml"),),
        "figures": (Figure("Displacement against time", png(10), "every bundle"),
                    Figure("Tension map", None, "this version draws none")),
        "video_still": png(200), "robustness": robustness}
    return Page(**{**fields, **changes})


class Parsed(HTMLParser):
    """The page's tags with their attributes, and the text of every table cell by table."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.tables: list[dict[str, Any]] = []
        self._cell: list[str] | None = None
        self.text: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))
        if tag == "br" and self._cell is not None:
            self._cell.append(" ")
        elif tag == "table":
            self.tables.append({"class": dict(attrs).get("class"), "rows": []})
        elif tag == "tr":
            self.tables[-1]["rows"].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1]["rows"][-1].append(" ".join("".join(self._cell).split()))
            self._cell = None

    def handle_data(self, data: str) -> None:
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)

    def table(self, cls: str) -> list[list[str]]:
        return next(t["rows"] for t in self.tables if t["class"] == cls)

    def facts(self) -> dict[str, str]:
        return {row[0]: row[1] for t in self.tables if t["class"] == "facts" for row in t["rows"]}


def test_every_user_string_is_escaped_and_bounded():
    long_name = "A" * 100_000
    text = render(page())
    parsed = Parsed(text)
    assert [tag for tag, _ in parsed.tags if tag in ("script", "link", "iframe")] == []
    assert not any("onerror" in attrs for _, attrs in parsed.tags)
    assert "\x1b" not in text and "<b>paper</b>" not in text
    shown = "".join(parsed.text)
    assert '<script>alert("x")</script>' in shown  # the name is shown as text, as entered
    assert "<b>paper</b>" in shown and "dir/<load>.toml" in shown
    assert len(render(page(load=LoadUnit.from_dict({**LOAD, "name": long_name})))) < len(
        text) + 2000, "a 100 kB name does not bury the page"


def test_every_angle_bracket_of_the_page_opens_a_tag():
    """Text that reads "< 40 mm" is written as &lt;: a raw "<" is a parse error in HTML, which
    browsers forgive and validators, archivers and converters do not."""
    text = render(page())
    assert re.findall(r"<(?![A-Za-z/!])", text) == []


def test_the_level_table_gives_each_eumos_criterion_its_figure_limit_and_verdict():
    parsed = Parsed(render(page()))
    head, *rows = parsed.table("levels")
    # limits of a 0.804 m load: 10 % = 80.4 mm, 5 % = 40.2 mm; 40 mm in the lowest 20 cm
    assert head[:5] == ["Level", "Elastic max limit ≤ 80.4 mm (10 % of height)",
                        "Permanent max limit ≤ 40.2 mm (5 % of height)",
                        "Lowest 20 cm, permanent limit < 40 mm (bundles below 20 cm)",
                        "Damage limit none"]
    assert head[-1] == "Result"
    assert rows[0][:5] == ["0.30 g", "11.8 mm (1.5 %) pass", "8.9 mm (1.1 %) pass",
                           "8.8 mm pass", "none pass"]
    assert rows[0][-1] == "PASS"
    # 123.4 mm is 15.3 % of 804 mm: over the elastic limit; the damage is named
    assert rows[1][:5] == ["0.40 g", "123.4 mm (15.3 %) fail", "35.0 mm (4.4 %) pass",
                           "39.0 mm pass", "L2C1R1 toppled fail"]
    assert rows[1][-1] == "FAIL"


def test_the_page_says_it_is_a_simulation_and_by_which_version_of_the_bench():
    text = " ".join(render(page()).split())
    assert f"virtual ESTL acceleration bench of wrapbench {metadata.version('wrapbench')}" in text
    assert "a simulation, not a physical test" in text


def test_sections_name_the_load_the_program_as_entered_the_web_and_the_cycle():
    parsed = Parsed(render(page()))
    facts = parsed.facts()
    assert facts["Pallet"] == "1.200 × 0.800 × 0.144 m, 25.0 kg"
    assert facts["Stack"] == "2 layers, columnar, 16 bundles on the first, 32 in all"
    assert facts["bottom_wraps"] == "3" and facts["up_overlap"] == "0.5"
    assert facts["Machine"].startswith("12 rpm, 3 s to start and to stop, carriage up to 0.1 m/s")
    assert re.fullmatch(r"[\d.]+ m² \([\d.]+ kg\), [\d.]+ m laid, .* revolutions",
                        facts["Web laid"])
    assert re.fullmatch(r"\d+ s per pallet, \d+ pallets/h", facts["Cycle time"])
    assert facts["Tested"].startswith("16 h after wrapping")
    bands = WrapFormat.from_dict({"material": "lldpe", "web_width_m": 0.5, "band": [
        {"from_m": 0.0, "to_m": 0.45, "layers": 3, "tension_n": 250.0}]}, "wrap.toml", 0.804)
    assert Parsed(render(page(wrap=bands))).facts()["band 1"] == "0.000–0.450 m, 3 layers at 250 N"
    assert "None: the unit was tested unwrapped." in render(page(wrap=None))
    friction = parsed.table("num")  # the first: friction pairs, then the program's steps
    assert friction[0] == ["Friction pair (the load file)", "static", "kinetic"]
    assert ["sled–pallet", "0.450", "0.340"] in friction


def test_figures_are_inlined_and_a_missing_one_says_not_available():
    text = render(page())
    parsed = Parsed(text)
    sources = [attrs["src"] for tag, attrs in parsed.tags if tag == "img"]
    assert len(sources) == 2  # the displacement plot and the video's still
    prefix = "data:image/png;base64,"
    assert all(s is not None and s.startswith(prefix) for s in sources)
    assert base64.b64decode(str(sources[0])[len(prefix):]) == png(10)
    assert "Tension map: not available — this version draws none" in " ".join(
        "".join(parsed.text).split())


def test_the_video_is_beside_the_page_browsers_first_with_its_still_for_print():
    parsed = Parsed(render(page()))
    sources = [(a["src"], a["type"]) for tag, a in parsed.tags if tag == "source"]
    assert sources == [("test.webm", "video/webm"), ("test.mp4", "video/mp4")]
    links = [a["href"] for tag, a in parsed.tags if tag == "a"]
    assert links == ["test.webm", "test.mp4"]
    assert not any(tag == "video" for tag, _ in Parsed(render(page(video_still=None))).tags)


def test_a_worst_sample_below_the_margin_goal_says_it_only_had_to_pass():
    """The search asks its margin of its own samples; the verification's only have to pass,
    and a page that shows both margins says which is which."""
    worst = Trial(True, 0.06, "long", {"elastic_max_m": 0.0459, "permanent_max_m": 0.0445},
                  {"friction": {"sled_pallet": {"static": 0.45, "kinetic": 0.4}},
                   "mass_scale": 1.0, "hours_since_wrapping": 16.0})
    facts = Parsed(render(page(Robustness(PassProbability(8, 8), worst,
                                          SearchFacts(0.20, 0.2, 48))))).facts()
    assert facts["Worst sample"].endswith("passed (below the goal of 0.20: these samples had "
                                          "only to pass)")
    assert "the answer's margin in the search's own samples 0.20" in facts["Search"]


def test_recommend_shows_the_pass_probability_with_its_interval_and_the_worst_sample():
    worst = Trial(True, 0.41, "short", {"elastic_max_m": 0.0213, "permanent_max_m": 0.0102},
                  {"friction": {"sled_pallet": {"static": 0.45, "kinetic": 0.4}},
                   "mass_scale": 1.02, "hours_since_wrapping": 16.0})
    robust = Robustness(PassProbability(7, 8), worst, SearchFacts(0.45, 0.2, 40))
    facts = Parsed(render(page(robust))).facts()
    # Wilson 95 % for 7 of 8: centre (0.875 + 1.96²/16) / (1 + 1.96²/8) = 0.753, half width
    # 1.96 / 1.480 * sqrt(0.875 * 0.125 / 8 + 1.96² / 256) = 0.224: 53 % to 98 %
    assert facts["Pass probability"] == "88 % (7 of 8 samples; 95 % interval 53 %–98 %, Wilson)"
    assert facts["Search"] == ("40 candidate programs; the answer's margin in the search's "
                               "own samples 0.45 (goal 0.20)")
    assert facts["Worst sample"] == ("short side, margin 0.41, elastic 21.3 mm, permanent "
                                     "10.2 mm, passed")
    assert "sled_pallet 0.450/0.400" in facts["Its draw"]
    assert "mass × 1.020" in facts["Its draw"]
    policy = Robustness(PassProbability(8, 8), worst, SearchFacts(0.45, 0.2, None))
    assert Parsed(render(page(policy))).facts()["Search"] == ("a trained policy's proposal, "
                                                              "verified in simulation")


def test_what_the_command_warned_about_is_on_the_page_too():
    """A page is handed on without the terminal it was made in: a warning given on stderr (a
    web that does not close round the load) must be on it, escaped like any user text."""
    said = ("the web does not close round the load from 0.13 to 0.22 m <b>",)
    html = render(page(warnings=said))
    assert ("section", {"class": "warnings"}) in Parsed(html).tags
    assert "the web does not close round the load from 0.13 to 0.22 m &lt;b&gt;" in html
    assert 'class="warnings"' not in render(page())


def test_the_page_states_its_test_conditions_when_given():
    said = "sled: the level reached in 0.05 s <held>"
    assert "Test conditions: sled: the level reached in 0.05 s &lt;held&gt;." in render(
        page(conditions=said))
    assert "Test conditions" not in render(page())


def test_the_friction_table_says_whether_it_was_calibrated():
    """A load file's friction may be a guess (CONTRACTS' example values); a report must not
    show it as if measured."""
    calibrated = page(inputs=(("load unit", "load.toml"), ("calibration", "cal.json")))
    heads = [t["rows"][0][0] for t in Parsed(render(calibrated)).tables]
    assert "Friction pair (calibrated)" in heads


def test_the_load_section_says_whether_the_bundles_give_was_assumed():
    """No source gives a bundle's give under a web and a film answer leans on it
    (docs/recommend.md): a report on the PET preset's says it is assumed; one whose load file
    gives its own says whose it is."""
    assumed = Parsed(render(page())).facts()["Bundles' give under the web"]
    assert assumed.startswith("600 kN/m per m of edge, edges of 45 mm radius: assumed")
    assert "measure yours" in assumed
    measured = LoadUnit.from_dict({**LOAD, "bundle": {"preset": "PET6x1.5L",
                                                      "corner_stiffness_n_per_m2": 2.0e5}})
    given = page(load=measured)
    assert Parsed(render(given)).facts()["Bundles' give under the web"] == (
        "200 kN/m per m of edge, edges of 45 mm radius: the load file's")
    calibrated = page(load=measured, inputs=(("load unit", "l.toml"), ("calibration", "c.json")))
    assert Parsed(render(calibrated)).facts()["Bundles' give under the web"].endswith(
        "the load file's, with its calibration")


def test_the_wrap_cell_says_where_the_peak_was_and_whether_the_test_added_it():
    """A roped program's rope bears its laid tension at every level: a peak at the level's
    first instant is the tension as laid, not what the pulse added."""
    def report(t_s: float | None) -> WrapReport:
        rope = Place("ring", "corner -x-y", 0.115, 0.11, 217.7, t_s, 0.0, 0.0, 0.115, 0.115)
        return WrapReport((), 0.11, 0.0, places=(rope,))

    def cell(w: WrapReport) -> str:
        v = replace(level(0.5, 0.01, 0.005, 0.004), wrap=w)
        run = BenchRun(Verdict(0.804, (v,)), (), 50)
        rows = Parsed(render(page(tested=(OrientationRun(None, LoadUnit.from_dict(LOAD).layout(),
                                                                 run),)))).tables
        levels = next(t for t in rows if t["class"] == "levels")
        return str(levels["rows"][1][-2])

    assert cell(report(1 / 240)) == "11 % of strength, as laid (ring corner -x-y, 0.12 m)"
    assert cell(report(None)).startswith("11 % of strength, as laid")
    assert cell(report(0.42)) == "11 % of strength, at 0.42 s (ring corner -x-y, 0.12 m)"


def test_simulate_s_samples_say_how_sure_without_a_search_and_where_a_level_stopped():
    """`simulate --samples` has no search and no margin goal: the page gives the pass
    probability and the worst sample, which a failed level stopped once decided."""
    worst = Trial(False, -1.05, "short", {"elastic_max_m": 0.1152, "permanent_max_m": 0.1152,
                                          "stopped_early": "elastic displacement 115 mm past "
                                                           "113 mm"},
                  {"friction": {"sled_pallet": {"static": 0.45, "kinetic": 0.4}},
                   "mass_scale": 1.0, "hours_since_wrapping": 16.0})
    facts = Parsed(render(page(Robustness(PassProbability(5, 8), worst)))).facts()
    assert "Search" not in facts
    assert facts["Pass probability"] == "62 % (5 of 8 samples; 95 % interval 31 %–86 %, Wilson)"
    assert facts["Worst sample"] == ("short side, margin -1.05, elastic 115.2 mm, permanent "
                                     "115.2 mm, failed (its level stopped once decided: elastic "
                                     "displacement 115 mm past 113 mm)")

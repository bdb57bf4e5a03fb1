"""The one-page report's content and its HTML (recommender/html_report.py makes and writes it).

The page is built from the run's own objects (load unit, wrap as entered, bench runs), and every
string is escaped and bounded: a load name can hold anything. Figures are inlined as data: URIs;
the test video sits beside the page (a data: URI would make the page megabytes), WebM first for
browsers and MP4 for players, its still inlined for print. The style (recommender/data/
report.css) lays the page on A4 for print without cutting tables or figures.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from recommender.search import Trial
from recommender.text import (
    TIGHT_WRAP_HINT,
    level_result,
    machine_text,
    mm_text,
    sample_figures,
    sequence_text,
    step_cells,
    wrapped,
)
from wrapenv import __version__
from wrapenv.bench import BenchRun, SimSettings
from wrapenv.config import printable
from wrapenv.eumos import NO_DAMAGE, Criterion, LevelVerdict, Verdict
from wrapenv.load import (
    PAIRS,
    PET_CORNER_STIFFNESS_N_PER_M2,
    Bundle,
    Layout,
    LoadUnit,
    Orientation,
)
from wrapenv.uncertainty import PassProbability
from wrapenv.wrap import WrapFormat, program_to_dict
from wrapenv.wrap_report import WrapReport

#: The page's style, inlined into it (screen, and A4 print without cut tables or figures).
CSS = Path(__file__).resolve().parent / "data" / "report.css"
#: The video files beside the page, the one browsers play first.
VIDEO_FILES = ("test.webm", "test.mp4")


@dataclass(frozen=True)
class Figure:
    title: str
    png: bytes | None  # None: not available
    caption: str       # what it shows, or why it is not available


@dataclass(frozen=True)
class OrientationRun:
    """One orientation's bench run: the EUMOS levels run on the unit laid out as `layout`."""

    orientation: Orientation | None  # None: as the load file lays it out
    layout: Layout
    run: BenchRun
    target_g: float | None = None


@dataclass(frozen=True)
class SearchFacts:
    """How `recommend` came to its answer: its margin in the search's own samples, the margin
    asked, and the candidates tried (None: a trained policy's proposal, no search)."""

    margin: float
    margin_goal: float
    candidates: int | None


@dataclass(frozen=True)
class Robustness:
    """How sure a verdict is over what the bench does not know: `recommend`'s verification of
    its answer, or the samples `simulate --samples` ran."""

    probability: PassProbability
    worst: Trial | None
    search: SearchFacts | None = None  # None: simulate's samples, no search


@dataclass(frozen=True)
class Page:
    """Everything report.html shows, gathered before a line of HTML is written: the page is
    then a pure function of it."""

    heading: str
    load: LoadUnit
    tested: tuple[OrientationRun, ...]
    wrap: WrapFormat | None  # as given or recommended, before relaxation (None: unwrapped)
    hours_since_wrapping: float
    inputs: tuple[tuple[str, str], ...]  # (what, file name)
    figures: tuple[Figure, ...]
    video_still: bytes | None  # None: no video
    robustness: Robustness | None = None
    #: What the command warned about on stderr (a web that does not close, a calibration
    #: accepted knowingly, a policy's extrapolation): a page handed on must say it too.
    warnings: tuple[str, ...] = ()
    #: How the levels were run (`recommender.text.conditions_text`): a report states them.
    conditions: str = ""


def _t(text: object, limit: int = 300) -> str:
    """A user's (or any) string as HTML text: printable, bounded, escaped."""
    return html.escape(printable(str(text), limit))


def _png(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _rows(cells: Iterable[Iterable[str]], tag: str = "td") -> str:
    """Table rows of cells that are already HTML."""
    return "".join("<tr>" + "".join(f"<{tag}>{c}</{tag}>" for c in row) + "</tr>\n"
                   for row in cells)


def _table(head: Iterable[str], body: Iterable[Iterable[str]], cls: str) -> str:
    return (f'<table class="{cls}"><thead>{_rows([head], "th")}</thead>'
            f"<tbody>{_rows(body)}</tbody></table>\n")


def _facts(rows: Iterable[tuple[str, str]]) -> str:
    """A two-column table: what, then its value (both already HTML)."""
    body = "".join(f'<tr><th scope="row">{k}</th><td>{v}</td></tr>\n' for k, v in rows)
    return f'<table class="facts"><tbody>{body}</tbody></table>\n'


def _side(t: OrientationRun) -> str:
    along = t.layout.pallet_size_m[0]
    if t.orientation is None:
        return f"pallet length ({along:.3f} m) along the motion, as the load file lays it out"
    return f"{t.orientation} side ({along:.3f} m) along the motion"


def _load_section(load: LoadUnit, layout: Layout, calibrated: bool) -> str:
    """The unit as simulated; its friction says where it came from (a load file's may be a
    guess, a calibration's was measured)."""
    p, b, s = load.pallet, load.bundle, load.stack
    per_layer = sum(1 for x in layout.bundles if x.layer == 1)
    facts = [
        ("Pallet", f"{p.length_m:.3f} × {p.width_m:.3f} × {p.height_m:.3f} m, {p.mass_kg:.1f} kg"),
        ("Bundle", f"{b.length_m:.3f} × {b.width_m:.3f} × {b.height_m:.3f} m, {b.mass_kg:.2f} kg"),
        ("Stack", f"{s.layers} layer{'s' * (s.layers != 1)}, {_t(s.pattern)}, {per_layer} "
                  f"bundles on the first, {len(layout.bundles)} in all"),
        ("Load height, gross mass", f"{load.load_height_m:.3f} m, {load.mass_kg:.0f} kg"),
        ("Pallet stopper on the sled", "yes" if load.pallet_stopper else "no"),
        ("Bundles' give under the web", _give_text(b, calibrated)),
    ]
    friction = [(name.replace("_", "–"), f"{load.friction.pair(name).static:.3f}",
                 f"{load.friction.pair(name).kinetic:.3f}") for name in PAIRS]
    return ("<section><h2>Load unit</h2>" + _facts(facts)
            + _table([f"Friction pair ({'calibrated' if calibrated else 'the load file'})",
                      "static", "kinetic"], friction, "num") + "</section>\n")


def _give_text(bundle: Bundle, calibrated: bool) -> str:
    """The edges' give and where it came from: no source gives it, and a film answer leans on
    it (docs/recommend.md, "A film answer and a give nobody measured")."""
    figure = (f"{bundle.corner_stiffness_n_per_m2 / 1e3:.0f} kN/m per m of edge, edges of "
              f"{bundle.edge_radius_m * 1000:.0f} mm radius")
    if bundle.corner_stiffness_n_per_m2 == PET_CORNER_STIFFNESS_N_PER_M2:
        return (f"{figure}: assumed, a shrink-wrapped PET bundle's, which no source gives "
                f"(docs/materials.md, B1); a film answer leans on it, so measure yours and "
                f"enter it in the load file")
    return f"{figure}: the load file's" + (", with its calibration" if calibrated else "")


def _program_rows(wrap: WrapFormat) -> list[tuple[str, str]]:
    """The program's settings as the WRAP.toml holds them, or the bands of a band form."""
    if wrap.program is None:
        return [(f"band {i}", f"{band.from_m:.3f}–{band.to_m:.3f} m, {band.layers:g} layers at "
                              f"{band.tension_n:.0f} N") for i, band in enumerate(wrap.bands, 1)]
    rows = []
    for key, value in program_to_dict(wrap.program).items():
        if key == "reinforcement":
            value = "; ".join(f"{r['wraps']} wraps at {r['from_m']:.3f} m, {r['tension_n']:.0f} N"
                              for r in value)
        rows.append((_t(key), _t(value)))
    return rows


def _wrap_section(wrap: WrapFormat | None, layout: Layout, hours: float) -> str:
    if wrap is None:
        return "<section><h2>Wrap</h2><p>None: the unit was tested unwrapped.</p></section>\n"
    used, cycle = wrap.material_used_on(layout), wrap.cycle_time_s
    what = ("The program as WRAP.toml's [program] holds it" if wrap.program is not None
            else "The bands")
    facts = [("Material", f"{_t(wrap.material.name)} ({_t(wrap.material_key)}), web "
                          f"{wrap.web_width_m:.2f} m"),
             ("Machine", machine_text(wrap)),
             ("Web laid", f"{used.area_m2:.2f} m² ({used.mass_kg:.3f} kg), "
                          f"{used.web_length_m:.1f} m laid, {used.roll_length_m:.1f} m from the "
                          f"roll, {used.revolutions:.1f} revolutions"),
             ("Cycle time", f"{cycle:.0f} s per pallet, "
                            f"{wrap.pallets_per_hour:.0f} pallets/h"),
             ("Tested", f"{hours:g} h after wrapping" + (
                 " (the tension relaxed by the material's law)" if hours > 0 else ""))]
    steps = [(str(i), *map(_t, step_cells(p, wrap, layout.load_height_m)))
             for i, p in enumerate(wrap.passes, 1)]
    return ("<section><h2>Wrap</h2>" + _facts(facts) + f"<h3>{what}</h3>"
            + _facts(_program_rows(wrap)) + "<h3>What the machine does, step by step</h3>"
            + _table(["Step", "Zone", "Wraps", "Overlap", "Carriage (web's lower edge)",
                      "Tension N"], steps, "num") + "</section>\n")


def _check(ok: bool) -> str:
    return f'<span class="{"ok" if ok else "bad"}">{"pass" if ok else "fail"}</span>'


def _level_row(verdict: Verdict, level: LevelVerdict, criteria: tuple[Criterion, ...],
               height_m: float) -> list[str]:
    cells = [f"{level.level_g:.2f} g"]
    for c in criteria:
        ok = level.criteria.get(c.key, False) and level.valid
        cells.append(f"{c.figure_text(level, height_m)} {_check(ok)}")
    ok = level.criteria.get(NO_DAMAGE, False) and level.valid
    cells.append(f'{_t(", ".join(level.damage) or "none")} {_check(ok)}')
    cells.append(mm_text(level.pallet_slip_m))
    cells.append(_wrap_cell(level.wrap))
    result = level_result(verdict, level)
    why = level.invalid_reason or level.stopped_early or level.not_at_rest
    reason = f" ({_t(why)})" if why else ""
    cells.append(f'<b class="{"ok" if result == "PASS" else "bad"}">{result}</b>{reason}')
    return cells


def _wrap_cell(w: WrapReport | None) -> str:
    """The level's peak wrap force, where and when: a peak before the pulse is the tension
    as laid (on a roped program, the rope's at every level), one during it what the test
    added."""
    if w is None:
        return "—"
    text = f"{100 * w.peak_utilisation:.0f} % of strength"
    if w.critical:
        place = w.critical[0]
        # settling, or the level's first step (the report's runs are at the default step)
        laid = place.t_s is None or place.t_s <= SimSettings().timestep_s + 1e-9
        when = "as laid" if laid else f"at {place.t_s:.2f} s"
        text += f", {when} ({_t(place.element)} {_t(place.where)}, {place.height_m:.2f} m)"
    if w.torn:
        text += f", torn at {', '.join(f'{z:.2f}' for z in w.torn_at_m)} m"
    return text


def _highest(t: OrientationRun) -> str:
    best = t.run.verdict.highest_passed_g
    return "none" if best is None else f"{best:.2f} g"


def _levels_section(t: OrientationRun) -> str:
    v = t.run.verdict
    h, criteria = v.load_height_m, v.criteria()
    head = (["Level"] + [f"{_t(c.label)}<br><small>limit {_t(c.describe(h, '≤'))}</small>"
                         for c in criteria]
            + ["Damage<br><small>limit none</small>", "Pallet slip", "Wrap (peak force)",
               "Result"])
    target = f", target {t.target_g:.2f} g" if t.target_g is not None else ""
    sequence = sequence_text(v) + (" (permanent: since it was put on the sled)"
                                   if v.sequence == "cumulative" and len(v.levels) > 1 else "")
    summary = (f"highest level passed: {_highest(t)}{target}; {sequence}"
               + ("" if v.valid else "; the simulation became unphysical (INVALID rows never "
                                     f"pass{TIGHT_WRAP_HINT if wrapped(v) else ''})"))
    return (f'<section class="levels"><h3>{_t(_side(t))}</h3>'
            + _table(head, [_level_row(v, level, criteria, h) for level in v.levels], "levels")
            + f"<p>{summary}</p></section>\n")


def _verdict(page: Page) -> str:
    passed = all(t.run.verdict.passed for t in page.tested)
    valid = all(t.run.verdict.valid for t in page.tested)
    word = "PASS" if passed else ("INVALID" if not valid else "FAIL")
    sides = "; ".join(f"{_t(_side(t))}: highest level passed {_highest(t)}"
                      for t in page.tested)
    return f'<p class="verdict {"ok" if passed else "bad"}"><b>{word}</b> — {sides}</p>\n'


def _robust_section(r: Robustness) -> str:
    p, search = r.probability, r.search
    low, high = p.interval
    facts = [("Pass probability", f"{100 * p.estimate:.0f} % ({p.passed} of {p.samples} "
                                  f"samples; 95 % interval {100 * low:.0f} %–{100 * high:.0f} %, "
                                  "Wilson)")]
    if search is not None:
        facts.append(("Search", "a trained policy's proposal, verified in simulation"
                      if search.candidates is None else
                      f"{search.candidates} candidate programs; the answer's margin in the "
                      f"search's own samples {search.margin:.2f} (goal {search.margin_goal:.2f})"))
    if r.worst is not None:
        w, level = r.worst, r.worst.level
        below = (f" (below the goal of {search.margin_goal:.2f}: these samples had only to "
                 "pass)" if search is not None and w.passed and w.margin < search.margin_goal
                 else "")
        facts.append(("Worst sample", f"{_t(w.orientation)} side, margin {w.margin:.2f}, "
                      f"{sample_figures(level)}, "
                      f"{'passed' if w.passed else 'failed'}" + below
                      + (f" (its level stopped once decided: {_t(level['stopped_early'])})"
                         if level.get("stopped_early") else "")))
        facts.append(("Its draw", _t(_draw_text(w.sample), 1000)))
    return ('<section><h2>How sure: samples of what the bench does not know</h2>'
            + _facts(facts) + "</section>\n")


def _draw_text(sample: dict[str, Any]) -> str:
    """A sample's draw (`Sample.to_json`) in one line."""
    pairs = [f"{k} {v['static']:.3f}/{v['kinetic']:.3f}" for k, v in sample["friction"].items()]
    scales = [f"{k.removesuffix('_scale')} × {v:.3f}" for k, v in sample.items()
              if k.endswith("_scale") and isinstance(v, float)]
    return "friction (static/kinetic) " + ", ".join(pairs) + "; " + ", ".join(scales)


def _figures_section(figures: tuple[Figure, ...]) -> str:
    out = []
    for f in figures:
        if f.png is None:
            out.append(f'<figure class="missing"><p><b>{_t(f.title)}</b>: not available — '
                       f"{_t(f.caption)}</p></figure>")
        else:
            out.append(f'<figure><img src="{_png(f.png)}" alt="{_t(f.title)}">'
                       f"<figcaption><b>{_t(f.title)}</b>: {_t(f.caption)}</figcaption></figure>")
    return "<section><h2>Figures</h2>" + "\n".join(out) + "</section>\n"


def _video_section(still: bytes | None) -> str:
    if still is None:
        return ""
    sources = "".join(f'<source src="{name}" type="video/{name.rsplit(".", 1)[1]}">'
                      for name in VIDEO_FILES)
    links = ", ".join(f'<a href="{name}">{name}</a>' for name in VIDEO_FILES)
    return (f'<section class="video"><h2>Test video</h2><figure><video controls '
            f'preload="metadata" poster="{_png(still)}">{sources}</video>'
            f'<img class="still" src="{_png(still)}" alt="the test at its largest displacement">'
            f"<figcaption>The highest level run, from the side camera (20 fps); the still shows "
            f"the moment of largest displacement. Files beside this page: {links}."
            f"</figcaption></figure></section>\n")


def _warnings_section(warnings: tuple[str, ...]) -> str:
    if not warnings:
        return ""
    items = "".join(f"<li>{_t(w, 1000)}</li>" for w in warnings)
    return f'<section class="warnings"><h2>Warnings</h2><ul>{items}</ul></section>\n'


def render(page: Page) -> str:
    """The page as HTML text."""
    inputs = "".join(f"<li>{_t(what)}: <code>{_t(name)}</code></li>" for what, name in page.inputs)
    tested = "".join(_levels_section(t) for t in page.tested)
    robust = _robust_section(page.robustness) if page.robustness is not None else ""
    warned = _warnings_section(page.warnings)
    calibrated = any(what == "calibration" for what, _ in page.inputs)
    conditions = (f'<p class="note">Test conditions: {_t(page.conditions, 1000)}.</p>'
                  if page.conditions else "")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_t(page.heading)}: {_t(page.load.name, 120)}</title>
<style>{CSS.read_text()}</style></head>
<body><header><h1>{_t(page.heading)}</h1>
<p class="name">{_t(page.load.name)}</p>
<p class="note">EUMOS 40509 test on the virtual ESTL acceleration bench of wrapbench
{_t(__version__)}: a simulation, not a physical test. Inputs:</p><ul>{inputs}</ul></header>
{_verdict(page)}{warned}{robust}{_load_section(page.load, page.tested[0].layout, calibrated)}
{_wrap_section(page.wrap, page.tested[0].layout, page.hours_since_wrapping)}
<section><h2>EUMOS 40509 levels</h2>{conditions}{tested}</section>
{_figures_section(page.figures)}{_video_section(page.video_still)}
</body></html>
"""

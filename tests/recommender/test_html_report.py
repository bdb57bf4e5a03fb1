"""The engineer's one-page report (recommender/html_report.py; `simulate --report`, `recommend
--report`): the page built without a browser (escaping, sections, EUMOS figures against their
limits, figures inlined, the video beside the page, the report folder checked before any work),
then a real report opened in headless Chromium: no console error, the level table and every image
shown, the video playable, printable to PDF."""

from __future__ import annotations

import base64
import fcntl
import json
import os
import re
import select
import shutil
import subprocess
import time
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from recommender.cli import main
from recommender.html_report import (
    PAGE,
    Figure,
    OrientationRun,
    Page,
    Robustness,
    check_report_folder,
    render,
    write_report,
)
from recommender.search import Trial
from recommender.uncertainty import PassProbability
from wrapenv.bench import BenchRun
from wrapenv.config import InputError
from wrapenv.eumos import LevelVerdict, Verdict
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

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
                                         ("L2C1R1 toppled",)))), ())
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


# --- the page, without a browser ---------------------------------------------------------------


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


def test_sections_name_the_load_the_program_as_entered_the_web_and_the_cycle():
    parsed = Parsed(render(page()))
    facts = parsed.facts()
    assert facts["Pallet"] == "1.200 × 0.800 × 0.144 m, 25.0 kg"
    assert facts["Stack"] == "2 layers, columnar, 16 bundles on the first, 32 in all"
    assert facts["bottom_wraps"] == "3" and facts["up_overlap"] == "0.5"
    assert facts["Machine"].startswith("12 rpm, carriage up to 0.10 m/s")
    assert re.fullmatch(r"[\d.]+ m² \([\d.]+ kg\), [\d.]+ m laid, .* revolutions",
                        facts["Web laid"])
    assert re.fullmatch(r"\d+ s per pallet, \d+ pallets/h", facts["Cycle time"])
    assert facts["OrientationRun"].startswith("16 h after wrapping")
    friction = parsed.table("num")  # the first: friction pairs, then the program's steps
    assert friction[0] == ["Friction pair", "static", "kinetic"]
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


def test_recommend_shows_the_pass_probability_with_its_interval_and_the_worst_sample():
    worst = Trial(True, 0.41, "short", {"elastic_max_m": 0.0213, "permanent_max_m": 0.0102},
                  {"friction": {"sled_pallet": {"static": 0.45, "kinetic": 0.4}},
                   "mass_scale": 1.02, "hours_since_wrapping": 16.0})
    robust = Robustness(PassProbability(7, 8), worst, 0.45, 0.2, 40)
    facts = Parsed(render(page(robust))).facts()
    # Wilson 95 % for 7 of 8: centre (0.875 + 1.96²/16) / (1 + 1.96²/8) = 0.753, half width
    # 1.96 / 1.480 * sqrt(0.875 * 0.125 / 8 + 1.96² / 256) = 0.224: 53 % to 98 %
    assert facts["Pass probability"] == "88 % (7 of 8 samples; 95 % interval 53 %–98 %, Wilson)"
    assert facts["Search"] == ("40 candidate programs; margin of the worst sample 0.45 "
                               "(goal 0.20)")
    assert facts["Worst sample"] == ("short side, margin 0.41, elastic 21.3 mm, permanent "
                                     "10.2 mm, passed")
    assert "sled_pallet 0.450/0.400" in facts["Its draw"]
    assert "mass × 1.020" in facts["Its draw"]


# --- the report folder -------------------------------------------------------------------------


def test_report_folder_is_checked_before_any_work(tmp_path, assert_input_error):
    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(InputError) as info:
        check_report_folder(a_file, [])
    assert_input_error(info.value, str(a_file), "--report")
    folder = tmp_path / "out"
    folder.mkdir()
    load = folder / PAGE
    load.write_text("name = 'x'")
    with pytest.raises(InputError, match="is an input"):
        check_report_folder(folder, [load])
    check_report_folder(tmp_path / "new" / "deeper", [])
    assert not (tmp_path / "new").exists(), "checking creates nothing"


def test_an_interrupted_report_leaves_nothing(tmp_path):
    def interrupted(stage: Path) -> Page:
        (stage / "displacement.png").write_bytes(png(1))
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_report(tmp_path / "new", interrupted)
    assert not (tmp_path / "new").exists()
    (tmp_path / "old").mkdir()
    with pytest.raises(KeyboardInterrupt):
        write_report(tmp_path / "old", interrupted)
    assert list((tmp_path / "old").iterdir()) == []


def test_simulate_refuses_a_report_folder_that_is_a_file_before_simulating(tmp_path, capsys,
                                                                          load_file):
    load = load_file()
    (tmp_path / "taken").write_text("x")
    code = main(["simulate", str(load), "--level", "0.2", "--report", str(tmp_path / "taken"),
                 "--json", str(tmp_path / "v.json")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--report" in err
    assert not (tmp_path / "v.json").exists()


# --- a real report in a real browser -----------------------------------------------------------

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="Chromium not found (`apt-get install chromium`; .ci/run installs it)")


class Chromium:
    """Headless Chromium driven over the DevTools protocol on a pipe (fds 3 and 4, messages
    ended by NUL): no network, no extra package."""

    def __init__(self, profile: Path) -> None:
        ours_in, theirs_in = os.pipe()
        theirs_out, ours_out = os.pipe()

        def pipes_on_3_and_4() -> None:
            read, write = (fcntl.fcntl(fd, fcntl.F_DUPFD, 10) for fd in (ours_in, ours_out))
            os.dup2(read, 3)
            os.dup2(write, 4)

        self.process = subprocess.Popen(
            [str(CHROMIUM), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--disable-background-networking", "--disable-component-update",
             f"--user-data-dir={profile}", "--remote-debugging-pipe", "about:blank"],
            pass_fds=(3, 4), preexec_fn=pipes_on_3_and_4, stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(ours_in)
        os.close(ours_out)
        self.send_fd, self.receive_fd = theirs_in, theirs_out
        self.buffer, self.next_id = b"", 0
        self.events: list[dict[str, Any]] = []
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target,
                                 flatten=True)["sessionId"]

    def _message(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self.buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.receive_fd], [], [], left)[0]:
                raise TimeoutError("Chromium did not answer")
            chunk = os.read(self.receive_fd, 1 << 20)
            if not chunk:
                raise EOFError("Chromium closed the pipe")
            self.buffer += chunk
        message, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(message)

    def call(self, method: str, page: bool = False, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params}
        if page:
            message["sessionId"] = self.session
        os.write(self.send_fd, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + 60
        while True:
            reply = self._message(deadline)
            if reply.get("id") == self.next_id:
                assert "error" not in reply, reply["error"]
                return reply["result"]
            self.events.append(reply)

    def wait_for(self, method: str) -> None:
        deadline = time.monotonic() + 60
        while not any(e.get("method") == method for e in self.events):
            self.events.append(self._message(deadline))

    def evaluate(self, expression: str) -> Any:
        result = self.call("Runtime.evaluate", page=True, expression=expression,
                           returnByValue=True, awaitPromise=True)
        assert "exceptionDetails" not in result, result
        return result["result"].get("value")

    def errors(self) -> list[str]:
        """Console errors, uncaught exceptions and the browser's own error log (a resource
        that failed to load, a blocked request) since the page was opened."""
        out = []
        for e in self.events:
            method, params = e.get("method"), e.get("params", {})
            if method == "Runtime.consoleAPICalled" and params["type"] in ("error", "assert"):
                out.append(json.dumps(params["args"]))
            elif method == "Runtime.exceptionThrown":
                out.append(json.dumps(params["exceptionDetails"]))
            elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
                out.append(params["entry"]["text"] + " " + params["entry"].get("url", ""))
        return out

    def close(self) -> None:
        try:
            self.call("Browser.close")
            self.process.wait(30)
        finally:
            if self.process.poll() is None:
                self.process.kill()
                self.process.wait()
            os.close(self.send_fd)
            os.close(self.receive_fd)


@pytest.fixture(scope="module")
def simulated_report(tmp_path_factory) -> Path:
    """`simulate --report` on a hostile-named two-bundle unit, wrapped, at two levels."""
    folder = tmp_path_factory.mktemp("simulate")
    load, wrap = folder / "load.toml", folder / "wrap.toml"
    load.write_text(f"name = {json.dumps(HOSTILE)}\n[pallet]\npreset = 'EUR'\n[bundle]\n"
                    "preset = 'PET6x1.5L'\n[stack]\nlayers = 1\npattern = 'explicit'\n"
                    "positions = [[-0.2, 0.0], [0.2, 0.0]]\n")
    wrap.write_text("material = 'kraft'\nweb_width_m = 0.5\n[program]\nbottom_wraps = 2\n"
                    "bottom_tension_n = 300.0\nup_overlap = 0.5\nmiddle_tension_n = 250.0\n"
                    "top_wraps = 1\ntop_tension_n = 250.0\n")
    code = main(["simulate", str(load), "--wrap", str(wrap), "--level", "0.2", "--level", "0.3",
                 "--report", str(folder / "report")])
    assert code == 0
    return folder / "report"


def test_simulate_report_writes_the_page_its_figures_and_both_videos(simulated_report):
    names = sorted(p.name for p in simulated_report.iterdir())
    assert names == ["displacement.png", PAGE, "test.mp4", "test.webm"]
    for video in ("test.mp4", "test.webm"):
        capture = cv2.VideoCapture(str(simulated_report / video))
        assert capture.isOpened() and capture.get(cv2.CAP_PROP_FRAME_COUNT) > 10
        capture.release()
    rows = Parsed((simulated_report / PAGE).read_text()).table("levels")[1:]
    assert [row[0] for row in rows] == ["0.20 g", "0.30 g"]


@needs_chromium
def test_the_report_opens_in_chromium_without_errors_showing_the_table_and_images(
        simulated_report, tmp_path):
    browser = Chromium(tmp_path / "profile")
    try:
        for domain in ("Page", "Runtime", "Log"):
            browser.call(f"{domain}.enable", page=True)
        browser.call("Page.navigate", page=True, url=(simulated_report / PAGE).as_uri())
        browser.wait_for("Page.loadEventFired")
        shown = browser.evaluate("""(async () => {
            const video = document.querySelector('video');
            if (video.readyState < 1) await new Promise(ok => {
                video.addEventListener('loadedmetadata', ok); video.addEventListener('error', ok);
                setTimeout(ok, 10000); });
            const rows = [...document.querySelectorAll('table.levels tbody tr')];
            const box = e => e.getBoundingClientRect();
            return {rows: rows.map(r => r.cells[0].textContent), title: document.title,
                    rowsShown: rows.every(r => box(r).height > 0 && box(r).width > 0),
                    images: [...document.images].map(i => ({complete: i.complete,
                        width: i.naturalWidth, shown: box(i).width > 0 || i.className})),
                    scripts: document.scripts.length,
                    video: {src: video.currentSrc, ready: video.readyState,
                            error: video.error && video.error.code,
                            duration: video.duration}};
        })()""")
        assert browser.errors() == []
        assert shown["rows"] == ["0.20 g", "0.30 g"] and shown["rowsShown"]
        assert shown["title"].startswith('Bench test report: <script>alert("x")</script>')
        assert shown["scripts"] == 0, "the hostile name stayed text"
        plot, still = shown["images"]
        assert plot == {"complete": True, "width": 990, "shown": True}
        assert still["complete"] and still["width"] == 960 and still["shown"] == "still"
        assert shown["video"]["src"].endswith("/test.webm") and shown["video"]["error"] is None
        assert shown["video"]["ready"] >= 1 and shown["video"]["duration"] > 1.0
        browser.call("Emulation.setEmulatedMedia", page=True, media="print")
        printed = browser.evaluate("""({video: getComputedStyle(document.querySelector('video'))
            .display, still: getComputedStyle(document.querySelector('img.still')).display})""")
        assert printed == {"video": "none", "still": "block"}
        pdf = base64.b64decode(browser.call("Page.printToPDF", page=True,
                                            preferCSSPageSize=True)["data"])
        assert pdf.startswith(b"%PDF") and len(re.findall(rb"/Type\s*/Page\b", pdf)) >= 2
    finally:
        browser.close()

"""The one-page report written (recommender/html_report.py; `simulate --report`, `recommend
--report`): the folder checked before any work, nothing left by an interrupted report, then a real
report opened in headless Chromium: no console error, the level table and every image shown, the
video playable, printable to PDF."""

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
from pathlib import Path
from typing import Any

import cv2
import pytest

from recommender.cli import main
from recommender.html_page import Page
from recommender.html_report import PAGE, check_report_folder, write_report
from tests.conftest import TINY_LOAD, to_toml
from tests.recommender.conftest import TWO_LAYERS_OF_FOUR
from wrapenv.config import InputError

#: Its simulated report is made once, in one test process (`--dist loadgroup`).
pytestmark = pytest.mark.xdist_group("html_report")

#: A load name that would break the page, its title or a plot if it were written raw.
HOSTILE = '<script>alert("x")</script><img src=x onerror=alert(1)> & $\\frac{$ \x1b[31m'


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
        (stage / "displacement.png").write_bytes(b"half a figure")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_report(tmp_path / "new", interrupted)
    assert not (tmp_path / "new").exists()
    (tmp_path / "old").mkdir()
    with pytest.raises(KeyboardInterrupt):
        write_report(tmp_path / "old", interrupted)
    assert list((tmp_path / "old").iterdir()) == []


def test_a_report_interrupted_before_its_files_go_in_leaves_the_old_one_whole(
        tmp_path, monkeypatch):
    """The new figures never land beside the old page: the files go in together."""
    folder = tmp_path / "old"
    folder.mkdir()
    for name, text in ((PAGE, "old page"), ("displacement.png", "old figure")):
        (folder / name).write_text(text)
    reads = Path.read_bytes

    def read_bytes(path: Path) -> bytes:
        if path.name == PAGE and path.parent != folder:
            raise KeyboardInterrupt   # the stage's page, read after its figures
        return reads(path)

    def make(stage: Path) -> Page:
        (stage / "displacement.png").write_bytes(b"new figure")
        return None  # type: ignore[return-value]

    monkeypatch.setattr("recommender.html_report.render", lambda page: "new page")
    monkeypatch.setattr(Path, "read_bytes", read_bytes)
    with pytest.raises(KeyboardInterrupt):
        write_report(folder, make)
    monkeypatch.undo()
    assert {p.name: p.read_text() for p in folder.iterdir()} == {
        PAGE: "old page", "displacement.png": "old figure"}


def test_simulate_refuses_a_report_folder_that_is_a_file_before_simulating(tmp_path, capsys,
                                                                          load_file):
    load = load_file()
    (tmp_path / "taken").write_text("x")
    code = main(["simulate", str(load), "--level", "0.2", "--report", str(tmp_path / "taken"),
                 "--json", str(tmp_path / "v.json")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--report" in err
    assert not (tmp_path / "v.json").exists()


@pytest.mark.parametrize("command", ["simulate", "recommend"])
def test_an_output_that_is_one_of_the_report_s_files_is_refused_before_any_work(
        command, tmp_path, capsys, load_file):
    """The report would replace it (or it the report's page)."""
    folder = tmp_path / "R"
    folder.mkdir()
    args = ["--level", "0.2"] if command == "simulate" else []
    code = main([command, str(load_file()), *args, "--report", str(folder),
                 "--json", str(folder / PAGE)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "--json" in err and f"is also --report ({PAGE})" in err
    assert list(folder.iterdir()) == []


def test_a_report_leaves_no_figure_of_an_earlier_report_in_its_folder(tmp_path, monkeypatch):
    """An unwrapped unit's page has no tension map: the wrapped run's, left in a reused folder,
    would sit beside a page that says there is none."""
    folder = tmp_path / "R"
    folder.mkdir()
    for name in (PAGE, "tension_map.png", "displacement.png"):
        (folder / name).write_text("earlier report")
    (folder / "notes.txt").write_text("mine")

    def make(stage: Path) -> Page:
        (stage / "displacement.png").write_bytes(b"new figure")
        return None  # type: ignore[return-value]

    monkeypatch.setattr("recommender.html_report.render", lambda page: "new page")
    write_report(folder, make)
    assert {p.name: p.read_text() for p in folder.iterdir()} == {
        PAGE: "new page", "displacement.png": "new figure", "notes.txt": "mine"}


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
    """`simulate --report` on a hostile-named two-bundle unit, wrapped, at two levels, and in
    two samples of what the bench does not know."""
    folder = tmp_path_factory.mktemp("simulate")
    load, wrap = folder / "load.toml", folder / "wrap.toml"
    load.write_text(to_toml({**TINY_LOAD, "name": HOSTILE}))
    wrap.write_text("material = 'kraft'\nweb_width_m = 0.5\n[program]\nbottom_wraps = 2\n"
                    "bottom_tension_n = 300.0\nup_overlap = 0.5\nmiddle_tension_n = 250.0\n"
                    "top_wraps = 1\ntop_tension_n = 250.0\n")
    code = main(["simulate", str(load), "--wrap", str(wrap), "--level", "0.2", "--level", "0.3",
                 "--samples", "2", "--report", str(folder / "report")])
    assert code == 0
    return folder / "report"


def test_a_simulate_report_repeats_the_warnings_given_on_stderr(tmp_path, capsys):
    """The bundled film program leaves the web open above its rope (README: `simulate` warns);
    the page handed on says so as the terminal did."""
    code = main(["simulate", "examples/pet_2layer_columnar.toml", "--wrap",
                 "examples/program_lldpe_reinforced.toml", "--level", "0.2",
                 "--report", str(tmp_path / "report")])
    warned = [line.split("warning: ", 1)[1] for line in capsys.readouterr().err.splitlines()
              if "warning: " in line]
    assert code == 0 and any("does not close round the load" in w for w in warned)
    page = (tmp_path / "report" / PAGE).read_text()
    section = re.search(r'<section class="warnings">(.*?)</section>', page)
    assert section is not None
    assert re.findall(r"<li>(.*?)</li>", section.group(1)) == [
        w.replace("'", "&#x27;") for w in warned]
    assert "Test conditions: sled: the level reached in 0.05 s, held 0.5 s," in page


def test_simulate_report_writes_the_page_its_figures_and_both_videos(simulated_report):
    names = sorted(p.name for p in simulated_report.iterdir())
    assert names == ["displacement.png", PAGE, "tension_map.png", "test.mp4", "test.webm"]
    for video in ("test.mp4", "test.webm"):
        capture = cv2.VideoCapture(str(simulated_report / video))
        assert capture.isOpened() and capture.get(cv2.CAP_PROP_FRAME_COUNT) > 10
        capture.release()
    levels = re.findall(r"<tr><td>(\d\.\d\d g)</td>", (simulated_report / PAGE).read_text())
    assert levels == ["0.20 g", "0.30 g"]


def test_a_simulate_report_with_samples_says_how_sure_without_a_search(simulated_report):
    page = (simulated_report / PAGE).read_text()
    facts = dict(re.findall(r'<tr><th scope="row">(.*?)</th><td>(.*?)</td></tr>', page))
    assert re.fullmatch(r"\d+ % \(\d of 2 samples; 95 % interval \d+ %–\d+ %, Wilson\)",
                        facts["Pass probability"])
    assert facts["Worst sample"].startswith("long side, margin ")
    assert "Search" not in facts


#: What the page shows once loaded (the video given up to 10 s to read its header).
SHOWN = """(async () => {
    const video = document.querySelector('video');
    if (video.readyState < 1) await new Promise(ok => {
        video.addEventListener('loadedmetadata', ok); video.addEventListener('error', ok);
        setTimeout(ok, 10000); });
    const box = e => e.getBoundingClientRect();
    const rows = [...document.querySelectorAll('table.levels tbody tr')];
    return {title: document.title, scripts: document.scripts.length,
            rows: rows.map(r => r.cells[0].textContent),
            rowsShown: rows.every(r => box(r).height > 0 && box(r).width > 0),
            facts: Object.fromEntries([...document.querySelectorAll('table.facts tr')].map(
                r => [r.cells[0].textContent, r.cells[1].textContent])),
            images: [...document.images].map(i => ({complete: i.complete, width: i.naturalWidth,
                                                   shown: box(i).width > 0 || i.className})),
            video: {src: video.currentSrc, ready: video.readyState,
                    error: video.error && video.error.code, duration: video.duration}};
})()"""
#: What print shows in the video's place.
PRINTED = """({video: getComputedStyle(document.querySelector('video')).display,
               still: getComputedStyle(document.querySelector('img.still')).display})"""


def open_in_chromium(page: Path, profile: Path) -> tuple[dict[str, Any], list[str], bytes]:
    """What the page shows, the errors the browser logged, and the page printed to PDF (with
    what print shows in the video's place checked)."""
    browser = Chromium(profile)
    try:
        for domain in ("Page", "Runtime", "Log"):
            browser.call(f"{domain}.enable", page=True)
        browser.call("Page.navigate", page=True, url=page.as_uri())
        browser.wait_for("Page.loadEventFired")
        shown = browser.evaluate(SHOWN)
        browser.call("Emulation.setEmulatedMedia", page=True, media="print")
        assert browser.evaluate(PRINTED) == {"video": "none", "still": "block"}
        pdf = base64.b64decode(browser.call("Page.printToPDF", page=True,
                                            preferCSSPageSize=True)["data"])
        return shown, browser.errors(), pdf
    finally:
        browser.close()


def assert_images_and_video_shown(shown: dict[str, Any], widths: list[int]) -> None:
    """Inlined plots of these widths in pixels (matplotlib's inches at 110 dpi) shown, then the
    video's 960 px still (shown in print only); the WebM chosen and readable."""
    *plots, still = shown["images"]
    assert plots == [{"complete": True, "width": w, "shown": True} for w in widths]
    assert still == {"complete": True, "width": 960, "shown": "still"}
    video = shown["video"]
    assert video["src"].endswith("/test.webm") and video["error"] is None
    assert video["ready"] >= 1 and video["duration"] > 1.0


@needs_chromium
def test_the_report_opens_in_chromium_without_errors_showing_the_table_and_images(
        simulated_report, tmp_path):
    shown, errors, pdf = open_in_chromium(simulated_report / PAGE, tmp_path / "profile")
    assert errors == []
    assert shown["rows"] == ["0.20 g", "0.30 g"] and shown["rowsShown"]
    assert shown["title"].startswith('Bench test report: <script>alert("x")</script>')
    assert shown["scripts"] == 0, "the hostile name stayed text"
    assert_images_and_video_shown(shown, [990, 1100])  # displacement (9 in), tension map (10 in)
    assert pdf.startswith(b"%PDF") and len(re.findall(rb"/Type\s*/Page\b", pdf)) >= 2


@pytest.mark.slow
@needs_chromium
def test_recommend_report_adds_how_sure_and_the_search(tmp_path):
    load = tmp_path / "small.toml"
    load.write_text(to_toml(TWO_LAYERS_OF_FOUR))   # a search of a few candidates in a minute
    code = main(["recommend", str(load), "--budget", "4", "--samples", "1", "--workers", "2",
                 "--orientation", "long", "--hours-since-wrapping", "0",
                 "--report", str(tmp_path / "report")])
    assert code == 0
    assert sorted(p.name for p in (tmp_path / "report").iterdir()) == [
        "displacement.png", PAGE, "search.png", "tension_map.png", "test.mp4", "test.webm"]
    shown, errors, _ = open_in_chromium(tmp_path / "report" / PAGE, tmp_path / "profile")
    assert errors == []
    assert shown["rows"] == ["0.20 g", "0.30 g", "0.40 g", "0.50 g"]
    assert re.fullmatch(r"\d+ % \(\d of 8 samples; 95 % interval \d+ %–\d+ %, Wilson\)",
                        shown["facts"]["Pass probability"])
    assert shown["facts"]["Search"].startswith("4 candidate programs")
    assert_images_and_video_shown(shown, [990, 1100, 770])  # displacement, tension map, search

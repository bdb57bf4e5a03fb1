"""The engineer's one-page report (`simulate --report DIR`, `recommend --report DIR`): what a test
lab would issue after a bench test, as one HTML page (recommender/html_page.py) that needs
nothing else to show or print, beside the figures it inlines and the test video.

The folder is checked before any simulation; the report is made in a staging folder and copied
in once whole, the page last, so an interrupted report leaves nothing.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path

from recommender.html_page import (
    VIDEO_FILES,
    Figure,
    OrientationRun,
    Page,
    Robustness,
    SearchFacts,
    render,
)
from recommender.search import Evaluation, Problem, SearchState, Verification
from recommender.text import conditions_text
from wrapenv.bench import BenchRun
from wrapenv.config import (
    InputError,
    check_output,
    check_output_folder,
    write_atomic,
    write_together,
)
from wrapenv.load import Layout, LoadUnit, Orientation
from wrapenv.profile import Profile, PulseProfile
from wrapenv.wrap import WrapFormat

PAGE = "report.html"
#: Everything a report writes into its folder (each checked before any simulation).
REPORT_FILES = (PAGE, "displacement.png", "tension_map.png", "search.png", *VIDEO_FILES)


def _inputs(inputs: Mapping[str, Path | None]) -> tuple[tuple[str, str], ...]:
    return tuple((what, str(path)) for what, path in inputs.items() if path is not None)


def _displacement(run: BenchRun, stage: Path, title: str, which: str) -> Figure:
    from recommender.report import plot_displacements

    png = _staged(stage / "displacement.png", plot_displacements(run, title=title))
    return Figure("Displacement against time", png, f"every bundle in the pallet's frame, "
                  f"one panel per level, the EUMOS limits dashed; {which}")


def _staged(path: Path, png: bytes) -> bytes:
    """A figure written into the report's staging folder (moved in whole at the end)."""
    path.write_bytes(png)
    return png


def _tension_map(run: BenchRun, layout: Layout, stage: Path, title: str) -> Figure:
    """The wrap's tension map (`report.plot_tension_map`), or why there is none."""
    from recommender.report import plot_tension_map

    if not any(trace.wrap is not None for trace in run.traces):
        return Figure("Tension map", None, "the unit was tested unwrapped")
    png = _staged(stage / "tension_map.png", plot_tension_map(run, layout, title=title))
    return Figure("Tension map", png, "the envelope unrolled, each place coloured by its peak "
                                      "force over what it bears, torn and opened places marked")


def _video(run: BenchRun, layout: Layout, wrap: WrapFormat | None, stage: Path) -> bytes:
    """test.mp4 and test.webm of the highest level run; returns the still."""
    from recommender.report import write_video

    top = max(run.traces, key=lambda trace: trace.level_g)
    mp4, webm = (stage / name for name in ("test.mp4", "test.webm"))
    return write_video(top, layout, wrap, mp4, also=(webm,))


def simulate_page(stage: Path, load: LoadUnit, run: BenchRun, laid: WrapFormat | None,
                  simulated: WrapFormat | None, orientation: Orientation | None, hours: float,
                  inputs: Mapping[str, Path | None], warnings: tuple[str, ...],
                  profiles: Sequence[Profile], robustness: Robustness | None = None) -> Page:
    """`simulate --report`: the levels run (on `profiles`), the wrap as entered (`laid`) and
    as simulated (calibrated, relaxed) for the video, the warnings the command gave, and the
    samples' pass probability (`--samples`)."""
    layout = load.layout(orientation)
    figures = (_displacement(run, stage, load.name, "the levels in the table above"),
               _tension_map(run, layout, stage, load.name))
    return Page("Bench test report", load, (OrientationRun(orientation, layout, run),), laid, hours,
                _inputs(inputs), figures, _video(run, layout, simulated, stage), robustness,
                warnings=warnings, conditions=conditions_text(profiles, run))


def recommend_page(stage: Path, problem: Problem, check: Verification, best: Evaluation,
                   state: SearchState | None, inputs: Mapping[str, Path | None],
                   warnings: tuple[str, ...], candidates: int | None = None) -> Page:
    """`recommend --report`: the verified EUMOS sequence of every orientation, how sure the
    recommendation is, the search (none for a policy's proposal; `candidates`: those tried in
    every round, default the answering round's); the figures and the video of the weakest
    orientation; the warnings the command gave."""
    from recommender.report import plot_search

    s, load, weakest = problem.settings, problem.load, check.weakest
    plotted = None if state is None else len(state.history)
    tried = plotted if candidates is None else candidates
    targets = dict(s.targets)
    tested = tuple(OrientationRun(o, load.layout(o), run, targets[o])
                   for o, run in check.runs.items())
    run, layout = check.runs[weakest], load.layout(weakest)
    which = f"the {weakest} side along the motion, the weaker"
    search = (Figure("Search", None, "a trained policy proposed the program: there was no "
                     "search") if state is None else
              Figure("Search", _staged(stage / "search.png",
                                       plot_search(state.history, best, s.margin_goal)),
                     "every candidate's web against its worst sample's EUMOS margin"
                     + ("" if tried == plotted else " (the round that answered)")))
    figures = (_displacement(run, stage, load.name, which),
               _tension_map(run, layout, stage, load.name), search)
    robust = Robustness(check.probability, check.worst,
                        SearchFacts(best.margin, s.margin_goal, tried))
    return Page("Recommended wrapping program", load, tested, best.wrap,
                s.hours_since_wrapping, _inputs(inputs), figures,
                _video(run, layout, problem.simulated(best.wrap), stage), robust, warnings,
                conditions_text((PulseProfile(s.target_g),), run))


def check_report_folder(folder: Path, inputs: Iterable[str | Path], flag: str = "--report") -> None:
    """Before any simulation: the folder exists as one (every file the report writes can be
    written and is none of the inputs), or it can be created."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InputError(str(folder), flag, "exists and is not a folder")
    if not folder.exists():
        check_output_folder(folder, flag)
        return
    for name in REPORT_FILES:
        check_output(folder / name, flag, inputs=inputs)


def report_outputs(folder: Path | None, flag: str = "--report") -> dict[str, Path | None]:
    """The files a report writes, by the name an error gives each (for `check_distinct`: no
    other output may be one of them); none when no report was asked for."""
    if folder is None:
        return {}
    return {f"{flag} ({name})": Path(folder) / name for name in REPORT_FILES}


def write_report(folder: Path, make: Callable[[Path], Page]) -> Path:
    """`make(stage)` writes the figures and the video into a staging folder and returns the
    page; then the files are written into `folder` together (`write_together`), the page last.
    The stage is a temporary folder of the system's, so an interrupted report leaves nothing
    in `folder` (nor the folder if it made it), and a report that was there stays whole unless
    the interrupt falls between two of the final renames (each file is put in place whole, one
    after another); a killed one leaves its stage where temporary files go."""
    folder = Path(folder)
    created = not folder.exists()
    stage = Path(tempfile.mkdtemp(prefix="wrapbench-report-"))
    try:
        write_atomic(stage / PAGE, render(make(stage)).encode())
        folder.mkdir(parents=True, exist_ok=True)
        written = sorted(stage.iterdir(), key=lambda p: p.name == PAGE)
        write_together({folder / path.name: path.read_bytes() for path in written})
        for name in set(REPORT_FILES) - {path.name for path in written}:
            (folder / name).unlink(missing_ok=True)   # an earlier report's, not this page's
    except BaseException:
        if created:
            shutil.rmtree(folder, ignore_errors=True)
        raise
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return folder / PAGE

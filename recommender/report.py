"""Reports for people: displacement against time with the EUMOS limits drawn, the search's
material against margin, the wrap's tension map, and a video of a simulated test. The plots
return their PNG, for the caller to write and the one-page report (recommender/html_report.py)
to inline; the video is written, and its still returned."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Colormap, Normalize
from matplotlib.figure import Figure

from calibration.report import png
from recommender.text import level_result
from wrapenv.bench import BenchRun
from wrapenv.config import printable
from wrapenv.eumos import ELASTIC, PERMANENT, LevelVerdict, Verdict
from wrapenv.load import Layout
from wrapenv.render import Renderer, fitting_camera, torn_net
from wrapenv.trace import Trace
from wrapenv.wrap import WrapFormat
from wrapenv.wrap_geometry import CORNER_NAMES, corner_positions_m
from wrapenv.wrap_report import Place, WrapReport

if TYPE_CHECKING:
    from recommender.search import Evaluation

#: Layers' colours: matplotlib's tab10 without its orange and red, which draw the limits.
LAYER_COLOURS = tuple(colormaps["tab10"](i) for i in (0, 2, 4, 5, 6, 7, 8, 9))


def plot_displacements(run: BenchRun, title: str = "") -> bytes:
    """One panel per level: each bundle's displacement in the pallet frame against time, from
    where it stood when the level began, coloured by layer, the bundle of the highest peak named,
    with the elastic limit, and the permanent one where the level began where the unit was put
    on the sled; in a cumulative sequence the title adds the permanent displacement since then
    (what the permanent limit judges), and in its later levels that limit."""
    n = len(run.traces)
    fig = Figure(figsize=(9, 2.8 * n + 0.6), layout="constrained")
    axes = fig.subplots(n, 1, squeeze=False, sharex=True)
    for ax, trace, level in zip(axes[:, 0], run.traces, run.verdict.levels, strict=True):
        plot_level(ax, trace, level, run.verdict)
    axes[-1, 0].set_xlabel("time from pulse start [s]")
    if title:
        # a load's name is the user's: bounded, and never read as mathtext ("$" would be)
        fig.suptitle(printable(title, 120), fontsize=11, parse_math=False)
    return png(fig)


#: A level whose bundles began further than this from where the unit was put on the sled is
#: a later one of a cumulative sequence (0.1 mm: far above rounding, far below any figure).
MOVED_BEFORE_M = 1e-4


def plot_level(ax: Axes, trace: Trace, level: LevelVerdict, verdict: Verdict) -> None:
    """A level's panel (`level`, one of `verdict`'s, titled with the word the text and JSON
    give it): a unit has dozens of bundles, too many to tell apart by colour, so the legend
    names the layers and the one bundle whose displacement peaked highest (the elastic
    figure's; the permanent one may be another's). A later level of a cumulative sequence
    draws no permanent limit over its own displacements: its title gives the permanent
    displacement since the unit was put on the sled, and that limit."""
    height_m = verdict.load_height_m
    disp_mm = trace.bundle_displacement_m() * 1000
    layers = trace.layers if trace.layers is not None else np.ones(len(trace.names), int)
    for layer in np.unique(layers):
        colour = LAYER_COLOURS[(layer - 1) % len(LAYER_COLOURS)]
        for j, k in enumerate(np.flatnonzero(layers == layer)):
            ax.plot(trace.t_s, disp_mm[:, k], lw=0.7, color=colour,
                    alpha=0.8, label=f"layer {layer}" if j == 0 else None)
    most = int(np.argmax(disp_mm.max(axis=0)))
    ax.plot(trace.t_s, disp_mm[:, most], lw=1.6, color="black",
            label=f"{trace.names[most]}, highest peak")
    # a later level of a cumulative sequence starts displaced: its own curves, from where the
    # level began, are not what the permanent limit judges, so the title gives that figure
    later = trace.moved_before_m() > MOVED_BEFORE_M
    for c, line in ((ELASTIC, "red"), (PERMANENT, "orange")):
        if c is PERMANENT and later:
            continue
        ax.axhline(c.limit_m(height_m) * 1000, color=line, ls="--",
                   label=f"{c.label.split()[0].lower()} limit ({100 * c.limit:g} % of height)")
    total_m = level.permanent_total_max_m
    limit = f" (limit {1000 * PERMANENT.limit_m(height_m):.1f} mm)" if later else ""
    total = (f", permanent since put on the sled {1000 * total_m:.1f} mm{limit}"
             if trace.origin_m is not None and total_m is not None else "")
    ax.set_title(f"{level.level_g:.2f} g: {level_result(verdict, level)}{total}", fontsize=10)
    ax.set_ylabel("displacement [mm]")
    ax.set_ylim(0, max(ELASTIC.limit_m(height_m) * 1000 * 1.3, float(disp_mm.max()) * 1.05))
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))


def plot_search(history: Sequence[Evaluation], best: Evaluation | None,
                margin_goal: float) -> bytes:
    """Every simulated candidate of a search: material against its worst sample's margin,
    robust passes in green, the recommendation circled: where the search found the cheap side
    of safe."""
    fig = Figure(figsize=(7, 4.5))
    ax = fig.subplots()
    simulated = [e for e in history if e.margins]
    passed = [e for e in simulated if e.robust_pass]
    failed = [e for e in simulated if not e.robust_pass]
    for group, colour, label in ((failed, "tab:red", "fails in a sample"),
                                 (passed, "tab:green", "passes in every sample")):
        if group:
            ax.scatter([e.mass_kg for e in group], [max(e.margin, -1.0) for e in group],
                       s=18, c=colour, label=label, alpha=0.8)
    if best is not None:
        ax.scatter([best.mass_kg], [best.margin], s=160, facecolors="none", edgecolors="black",
                   label="recommended")
    ax.axhline(margin_goal, color="grey", ls="--", lw=0.8, label="margin goal")
    ax.axhline(0.0, color="black", lw=0.6)
    ax.set_xlabel("material [kg]")
    ax.set_ylabel("EUMOS margin of the worst sample")
    skipped = len(history) - len(simulated)
    ax.set_title(f"search: {len(history)} candidates" + (
        f", {skipped} not simulated (heavier than a pass, or over the cycle limit)"
        if skipped else ""), fontsize=10)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return png(fig)


#: Codec and container by file suffix: MPEG-4 part 2 in MP4 for players (OpenCV's wheels write
#: no H.264), VP8 for browsers, which do not play MPEG-4 part 2. The VP8 goes through OpenCV's
#: Matroska muxer (WebM is a subset of Matroska): its WebM muxer takes the same stream but
#: prints a warning about the codec tag on stderr.
CODECS = {".mp4": ("mp4v", ".mp4"), ".webm": ("VP80", ".mkv")}


def plot_tension_map(run: BenchRun, layout: Layout, title: str = "") -> bytes:
    """The envelope unrolled, one panel per wrapped level: position round the load (from its
    -x-y corner, counter-clockwise seen from above) against height, every place coloured by its
    peak utilisation (face diagonals as patches, corner verticals as bars, rings as lines with
    their corners as squares), the load's corners and layer joints drawn, torn places crossed,
    an opened seam's rings dashed."""
    levels = [(v, t.wrap) for v, t in zip(run.verdict.levels, run.traces, strict=True)
              if t.wrap is not None]
    if not levels:
        raise ValueError("no wrapped level to map")
    fig = Figure(figsize=(10, 3.8 * len(levels) + 0.8), layout="constrained")
    axes = fig.subplots(len(levels), 1, squeeze=False)
    norm = Normalize(0.0, 1.0)
    cmap = colormaps["turbo"]
    for ax, (verdict, report) in zip(axes[:, 0], levels, strict=True):
        _map_places(ax, report, cmap, norm)
        _map_frame(ax, layout)
        top = report.critical[0] if report.critical else None
        worst = (f"; most loaded: {top.where} at {top.height_m:.3f} m, {top.utilisation:.0%}"
                 if top is not None else "")
        ax.set_title(f"{verdict.level_g:.2f} g{worst}", fontsize=10)
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=axes[:, 0].tolist(),
                 label="peak force / what the place bears", fraction=0.04)
    if title:
        fig.suptitle(printable(title, 120), fontsize=11, parse_math=False)
    return png(fig)


def _map_places(ax: Axes, report: WrapReport, cmap: Colormap, norm: Normalize) -> None:
    """Diagonals first (patches), then verticals, rings and their corners on top."""
    order = {"diagonals": 0, "vertical": 1, "ring": 2, "seam": 3}
    for p in sorted(report.places, key=lambda p: order[p.element]):
        colour = cmap(norm(p.utilisation))
        if p.element == "diagonals":
            ax.fill_between([p.s0_m, p.s1_m], p.z0_m, p.z1_m, color=colour, alpha=0.85, lw=0)
        elif p.element == "vertical":
            ax.plot([p.s0_m] * 2, [p.z0_m, p.z1_m], color=colour, lw=5, solid_capstyle="butt")
        elif p.element == "ring" and p.s0_m == p.s1_m:
            ax.scatter([p.s0_m], [p.z0_m], s=36, marker="s", color=colour, edgecolors="k",
                       linewidths=0.4, zorder=4)
        elif p.element == "ring":
            ax.plot([p.s0_m, p.s1_m], [p.z0_m] * 2, color=colour, lw=3,
                    ls="--" if p.opened else "-", zorder=3)
        else:
            ax.plot([p.s0_m, p.s1_m], [p.height_m] * 2, color=colour, lw=1.5, ls=":",
                    zorder=3)
            ax.annotate(f"seam {p.utilisation:.0%}" + (" (opened)" if p.opened else ""),
                        (p.s1_m, p.height_m), fontsize=7, ha="right", va="bottom")
        if p.torn or (p.opened and p.element == "seam"):
            _mark_failure(ax, p)


def _mark_failure(ax: Axes, p: Place) -> None:
    s, z = (p.s0_m + p.s1_m) / 2, (p.z0_m + p.z1_m) / 2
    ax.scatter([s], [z], marker="x", s=90, color="red", linewidths=2.2, zorder=6)
    ax.annotate("opened" if p.opened and not p.torn else "torn", (s, z), color="red",
                fontsize=8, xytext=(4, 4), textcoords="offset points", zorder=6)


def _map_frame(ax: Axes, layout: Layout) -> None:
    """The load's corners (vertical lines) and the pallet's top and layer joints (horizontal)."""
    corners = corner_positions_m(layout)
    for s in corners:
        ax.axvline(s, color="grey", ls="--", lw=0.7, zorder=5)
    names = ax.secondary_xaxis("top")
    names.set_xticks(corners, [n.replace("corner ", "") for n in (*CORNER_NAMES,
                                                                   CORNER_NAMES[0])],
                     fontsize=7)
    joints = sorted({round(b.centre_m[2] - b.size_m[2] / 2, 6) for b in layout.bundles})
    for z in joints:   # the pallet's top and every joint between layers
        ax.axhline(z, color="white", lw=1.0, ls="-.", zorder=5)
    ax.set_xlim(corners[0], corners[-1])
    ax.set_ylim(0.0, layout.load_height_m)
    ax.set_xlabel("position round the load from its -x-y corner, counter-clockwise [m]")
    ax.set_ylabel("height [m]")


def write_video(trace: Trace, layout: Layout, wrap: WrapFormat | None, path: str | Path,
                size: tuple[int, int] = (960, 600), fps: int = 20,
                also: tuple[Path, ...] = ()) -> bytes:
    """An MP4 of one simulated level from the side camera, at the recordings' 20 fps, and the
    same frames in every file of `also` (`CODECS` by suffix), each written whole or not at all.
    Returns the frame of the largest displacement as PNG: the video's still for print."""
    paths = [Path(path), *also]
    step = max(1, round(1 / (fps * float(np.median(np.diff(trace.t_s))))))
    shown = range(0, len(trace.t_s), step)
    displacement = trace.bundle_displacement_m().max(axis=1)
    peak = max(shown, key=lambda i: displacement[i])
    net = torn_net(wrap, layout, trace) if wrap is not None else None
    codecs = [CODECS[p.suffix] for p in paths]
    tmps = [p.with_name(f".{p.stem}.tmp{muxer}") for p, (_, muxer) in zip(paths, codecs,
                                                                          strict=True)]
    writers = [cv2.VideoWriter(str(t), cv2.VideoWriter.fourcc(*codec), fps, size)
               for t, (codec, _) in zip(tmps, codecs, strict=True)]
    try:
        try:
            if not all(w.isOpened() for w in writers):
                raise RuntimeError(f"OpenCV cannot write {', '.join(map(str, paths))}")
            with Renderer(layout, fitting_camera(layout, *size)) as renderer:
                for i in shown:
                    frame = cv2.cvtColor(renderer.trace_frame(trace, i, net), cv2.COLOR_RGB2BGR)
                    for writer in writers:
                        writer.write(frame)
                    if i == peak:
                        still = cv2.imencode(".png", frame)[1].tobytes()
        finally:
            for writer in writers:
                writer.release()
    except BaseException:
        for t in tmps:
            t.unlink(missing_ok=True)
        raise
    for t, p in zip(tmps, paths, strict=True):
        t.replace(p)
    return still

"""The displacement plot (`simulate --plot`, the report's first figure): a unit has dozens of
bundles, more than colours can tell apart, so each level's legend names the layers, the bundle
whose displacement peaked highest and the two limits."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from matplotlib.figure import Figure

from recommender.report import plot_level
from wrapenv.eumos import Verdict, evaluate
from wrapenv.trace import Trace


def three_bundles(moved_m: list[float]) -> Trace:
    """Two bundles on the pallet and one on top, each moved along x by `moved_m` in 1 s."""
    start = np.array([[-0.2, 0.0, 0.3], [0.2, 0.0, 0.3], [-0.2, 0.0, 0.6]])
    end = start + np.array([[m, 0.0, 0.0] for m in moved_m])
    return Trace(
        level_g=0.3, load_height_m=0.8, names=("L1C1R1", "L1C2R1", "L2C1R1"),
        bottom_z_m=np.array([0.15, 0.15, 0.45]), t_s=np.array([0.0, 1.0]),
        sled_accel_mps2=np.zeros(2), pallet_pos_m=np.zeros((2, 3)),
        pallet_rot=np.stack([np.eye(3)] * 2), bundle_pos_m=np.stack([start, end]),
        bundle_rot=np.stack([np.stack([np.eye(3)] * 3)] * 2), layers=np.array([1, 1, 2]),
    )


def legend_of(trace: Trace) -> list[str]:
    return [text.get_text() for text in panel(trace).get_legend().get_texts()]


def panel(trace: Trace) -> Any:
    ax = Figure().subplots()
    level = evaluate(trace)
    plot_level(ax, trace, level, Verdict(trace.load_height_m, (level,)))
    assert ax.get_legend() is not None
    return ax


def test_the_legend_names_each_layer_once_and_the_bundle_that_moved_most():
    assert legend_of(three_bundles([0.004, 0.030, 0.010])) == [
        "layer 1", "layer 2", "L1C2R1, highest peak",
        "elastic limit (10 % of height)", "permanent limit (5 % of height)"]


def test_curves_and_limits_are_drawn_in_millimetres():
    """On the 0.8 m unit the limits lie at 80 mm (10 %) and 40 mm (5 %); the bundle that moved
    30 mm ends its curve at 30; the axis shows the elastic limit with room above it."""
    ax = panel(three_bundles([0.004, 0.030, 0.010]))
    ys = {line.get_label(): list(line.get_ydata()) for line in ax.get_lines()}
    assert ys["L1C2R1, highest peak"] == pytest.approx([0.0, 30.0])
    assert ys["elastic limit (10 % of height)"] == pytest.approx([80.0, 80.0])
    assert ys["permanent limit (5 % of height)"] == pytest.approx([40.0, 40.0])
    assert ax.get_ylim() == pytest.approx((0.0, 80.0 * 1.3))


def test_the_bundle_that_moved_most_is_judged_by_its_largest_displacement():
    assert "L2C1R1, highest peak" in legend_of(three_bundles([0.004, 0.010, -0.050]))


def test_a_later_level_of_a_sequence_gives_the_permanent_limit_in_its_title_not_as_a_line():
    """The unit had moved 30 mm in earlier levels and moves 20 mm more: 50 mm since it was put
    on the sled, past the 40 mm limit (5 % of 0.8 m), while its own curve stays under 40 mm;
    a line at 40 mm over that curve would read as a pass."""
    level = three_bundles([0.004, 0.020, 0.010])
    origin = level.bundle_pos_m[0] - np.array([0.030, 0.0, 0.0])
    later = replace(level, origin_m=origin)
    assert later.moved_before_m() == pytest.approx(0.030)
    assert "permanent limit (5 % of height)" not in legend_of(later)
    assert panel(later).get_title().endswith(
        "FAIL, permanent since put on the sled 50.0 mm (limit 40.0 mm)")
    first = replace(level, origin_m=level.bundle_pos_m[0])
    assert "permanent limit (5 % of height)" in legend_of(first)
    assert "(limit" not in panel(first).get_title()


def test_a_level_met_in_a_run_that_later_blew_up_is_titled_as_the_text_reports_it():
    """VOID, as `simulate` prints it and its JSON says it (not passed): no level of a run that
    became unphysical is a pass (the panel said PASS)."""
    trace = three_bundles([0.004, 0.010, 0.010])
    met = evaluate(trace)
    blown = replace(met, level_g=0.4, passed=False, valid=False, invalid_reason="blew up")
    ax = Figure().subplots()
    plot_level(ax, trace, met, Verdict(trace.load_height_m, (met, blown)))
    assert met.passed and ax.get_title() == "0.30 g: VOID"


def test_importing_the_reports_leaves_the_callers_matplotlib_backend_alone():
    # a notebook that imports the library keeps its inline plots
    script = ("import matplotlib, recommender.report, calibration.report; "
              "print(matplotlib.get_backend())")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True, env=os.environ | {"MPLBACKEND": "svg"})
    assert done.stdout.strip() == "svg"

"""The displacement plot (`simulate --plot`, the report's first figure): a unit has dozens of
bundles, more than colours can tell apart, so each level's legend names the layers, the bundle
whose displacement peaked highest and the two limits."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
from matplotlib.figure import Figure

from recommender.report import plot_level
from wrapenv.eumos import evaluate
from wrapenv.trace import Trace


def three_bundles(moved_m: list[float]) -> Trace:
    """Two bundles on the pallet and one on top, each moved along x by `moved_m` in 1 s."""
    start = np.array([[-0.2, 0.0, 0.3], [0.2, 0.0, 0.3], [-0.2, 0.0, 0.6]])
    end = start + np.array([[m, 0.0, 0.0] for m in moved_m])
    return Trace(
        level_g=0.3, load_height_m=0.8, names=("L1C1R1", "L1C2R1", "L2C1R1"),
        bottom_z_m=np.array([0.15, 0.15, 0.45]), t_s=np.array([0.0, 1.0]),
        sled_accel_mps2=np.zeros(2), pallet_pos=np.zeros((2, 3)),
        pallet_rot=np.stack([np.eye(3)] * 2), bundle_pos=np.stack([start, end]),
        bundle_rot=np.stack([np.stack([np.eye(3)] * 3)] * 2), layers=np.array([1, 1, 2]),
    )


def legend_of(trace: Trace) -> list[str]:
    ax = Figure().subplots()
    plot_level(ax, trace, evaluate(trace), trace.load_height_m)
    legend = ax.get_legend()
    assert legend is not None
    return [text.get_text() for text in legend.get_texts()]


def test_the_legend_names_each_layer_once_and_the_bundle_that_moved_most():
    assert legend_of(three_bundles([0.004, 0.030, 0.010])) == [
        "layer 1", "layer 2", "L1C2R1, highest peak",
        "elastic limit (10 % of height)", "permanent limit (5 % of height)"]


def test_the_bundle_that_moved_most_is_judged_by_its_largest_displacement():
    assert "L2C1R1, highest peak" in legend_of(three_bundles([0.004, 0.010, -0.050]))


def test_importing_the_reports_leaves_the_callers_matplotlib_backend_alone():
    # a notebook that imports the library keeps its inline plots
    script = ("import matplotlib, recommender.report, calibration.report; "
              "print(matplotlib.get_backend())")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True, env=os.environ | {"MPLBACKEND": "svg"})
    assert done.stdout.strip() == "svg"

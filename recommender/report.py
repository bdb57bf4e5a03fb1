"""Plots of bench runs for people: displacement against time with the EUMOS limits drawn."""

from __future__ import annotations

import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from wrapenv.bench import BenchRun  # noqa: E402
from wrapenv.config import write_atomic  # noqa: E402
from wrapenv.eumos import ELASTIC_LIMIT_FRACTION, PERMANENT_LIMIT_FRACTION  # noqa: E402


def plot_displacements(run: BenchRun, path: str | Path, title: str = "") -> None:
    """One panel per level: each bundle's displacement in the pallet frame against time."""
    n = len(run.traces)
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.8 * n + 0.6), squeeze=False, sharex=True)
    h = run.verdict.load_height_m
    for ax, trace, verdict in zip(axes[:, 0], run.traces, run.verdict.levels, strict=True):
        disp_mm = trace.bundle_displacement_m() * 1000
        for k, name in enumerate(trace.names):
            ax.plot(trace.t_s, disp_mm[:, k], lw=0.8, label=name if k < 12 else None)
        ax.axhline(ELASTIC_LIMIT_FRACTION * h * 1000, color="red", ls="--",
                   label="elastic limit (10 % of height)")
        ax.axhline(PERMANENT_LIMIT_FRACTION * h * 1000, color="orange", ls="--",
                   label="permanent limit (5 % of height)")
        result = "PASS" if verdict.passed else ("INVALID" if not verdict.valid else "FAIL")
        ax.set_title(f"{verdict.level_g:.2f} g: {result}", fontsize=10)
        ax.set_ylabel("displacement [mm]")
        ax.set_ylim(0, max(ELASTIC_LIMIT_FRACTION * h * 1000 * 1.3, float(disp_mm.max()) * 1.05))
    axes[-1, 0].set_xlabel("time from pulse start [s]")
    axes[0, 0].legend(fontsize=6, ncol=4, loc="upper right")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    write_atomic(path, buf.getvalue())

"""Pictures of a fit for people: the loss against simulations spent, and the fitted against the
tracked slips of every compared body (`calibration.features`)."""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps, ticker
from matplotlib.figure import Figure

from calibration import features
from calibration.replay import Observation
from wrapenv.config import printable

#: Bodies' colours: a 3-layer unit's visible row and its pallet are 13 bodies, more than
#: matplotlib's 10 default colours tell apart; tab20's dark tones first, then its light ones.
BODY_COLOURS = [colormaps["tab20"](i) for i in (*range(0, 20, 2), *range(1, 20, 2))]


def png(fig: Figure) -> bytes:
    """A figure as PNG (the caller writes it, with the run's other outputs). Figures are made
    without pyplot, so importing a report module leaves the caller's matplotlib backend alone."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()


def loss_figure(curve: Sequence[tuple[int, float]], title: str = "") -> Figure:
    """Residual RMS (the square root of the loss) of the best point so far."""
    fig = Figure(figsize=(7, 3.6), layout="constrained")
    ax = fig.subplots()
    sims = [s for s, _ in curve]
    rms_mm = [1e3 * math.sqrt(loss) for _, loss in curve]
    ax.plot(sims, rms_mm, marker=".", lw=1)
    ax.set_yscale("log")
    for axis in (ax.yaxis.set_major_formatter, ax.yaxis.set_minor_formatter):
        axis(ticker.FormatStrFormatter("%g"))  # 0.6, not 6 x 10^-1
    ax.set_xlabel("simulations")
    ax.set_ylabel("residual RMS, best so far [mm]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    return fig


def overlay_figure(observations: Sequence[Observation],
                   fitted: Sequence[dict[str, np.ndarray] | None]) -> Figure:
    """One panel per recording: the tracked (dots) and one fitted replay's (lines) slip of every
    compared body across its contact, over the frames the bench can predict."""
    n = len(observations)
    fig = Figure(figsize=(9, 3.0 * n + 0.4), layout="constrained")
    axes = fig.subplots(n, 1, squeeze=False)
    for ax, obs, sim in zip(axes[:, 0], observations, fitted, strict=True):
        tracked = features.slips(obs.states, obs.bodies)
        replayed = (features.slips({k: (t, sim[k]) for k, (t, _) in obs.states.items()},
                                   obs.bodies) if sim is not None else {})
        for k, (name, frames) in enumerate(sorted(obs.frames.items())):
            colour = BODY_COLOURS[k % len(BODY_COLOURS)]
            t = obs.states[name][0][:frames]
            ax.plot(t, 1e3 * tracked[name][:frames], ".", ms=3, color=colour, label=name)
            if name in replayed:
                ax.plot(t, 1e3 * replayed[name][:frames], "-", lw=1, color=colour)
        ax.set_title(f"{printable(Path(obs.source).name)}: tracked (dots), one fitted replay "
                     "(lines)",
                     fontsize=9)
        ax.set_ylabel("slip on its support [mm]")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1, 0].set_xlabel("time [s]")
    return fig

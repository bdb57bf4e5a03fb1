"""The fit's pictures show the fit's numbers: the loss curve in millimetres of residual, and each
compared body's tracked slip beside its replay's, over the frames the bench can predict."""

from __future__ import annotations

import numpy as np
import pytest

from calibration import features
from calibration.replay import Observation
from calibration.report import loss_figure, overlay_figure, png
from wrapenv.load import LoadUnit
from wrapenv.profile import MeasuredProfile

FPS = 20.0


def _observation(source: str, slip_m_per_frame: float, frames: int = 10,
                 predictable: int = 8) -> Observation:
    """The 2-layer example's pallet seen sliding on the sled at a constant rate, unrotated (so
    its slip is its displacement along x), of which the bench predicts the first frames."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    t = np.arange(frames) / FPS
    xza = np.zeros((frames, 3))
    xza[:, 0] = slip_m_per_frame * np.arange(frames)
    profile = MeasuredProfile(np.arange(-20, 100) * 0.01, np.zeros(120))
    return Observation(source, load, None, profile, {"pallet": (t, xza)},
                       features.bodies(load.layout(), {"pallet"}), {"pallet": predictable},
                       np.zeros(2 * predictable), frozenset(), (0.3, 0.0))


def test_the_loss_curve_is_the_residual_rms_in_millimetres_on_a_log_scale():
    fig = loss_figure([(38, 4e-4), (76, 1e-4), (300, 2.5e-5)], "surrogate: 300 simulations")
    ax, = fig.axes
    line, = ax.lines
    assert line.get_xdata().tolist() == [38, 76, 300]
    assert line.get_ydata() == pytest.approx([20.0, 10.0, 5.0])  # 1e3 x sqrt(loss)
    assert ax.get_yscale() == "log"
    assert ax.get_title() == "surrogate: 300 simulations"
    assert png(fig)[:4] == b"\x89PNG"


def test_the_overlay_has_a_panel_per_recording_with_tracked_dots_and_replayed_lines():
    """The first take's pallet slid 2 mm a frame and its replay 1.5 mm; the second take has no
    replay (it blew up), so it shows its dots alone. Frames past the predictable 8 are left
    out: no fit read them."""
    takes = [_observation("rec/a-0.4g", 0.002), _observation("rec/b-0.5g", 0.003)]
    replay = {"pallet": np.column_stack([0.0015 * np.arange(10), np.zeros(10), np.zeros(10)])}
    fig = overlay_figure(takes, [replay, None])
    first, second = fig.axes[:2]
    assert len([ax for ax in fig.axes if ax.lines]) == 2
    dots, line = first.lines
    assert dots.get_linestyle() == "None" and dots.get_label() == "pallet"
    assert dots.get_xdata() == pytest.approx(np.arange(8) / FPS)
    assert dots.get_ydata() == pytest.approx(2.0 * np.arange(8))
    assert line.get_ydata() == pytest.approx(1.5 * np.arange(8))
    assert first.get_title().startswith("a-0.4g: ")
    only, = second.lines
    assert only.get_ydata() == pytest.approx(3.0 * np.arange(8))
    assert second.get_title().startswith("b-0.5g: ")

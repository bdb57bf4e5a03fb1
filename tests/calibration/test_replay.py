"""Reading a recording for the fit (calibration/replay.py): when the sled stopped."""

from __future__ import annotations

import numpy as np

from calibration.replay import stop_s

T = np.arange(0.0, 3.0, 0.01)


def pulse() -> np.ndarray:
    """A 4.4 m/s^2 pulse until 0.5 s, then braking at 1.1 m/s^2 until 1.5 s."""
    return np.where(T < 0.5, 4.4, np.where(T < 1.5, -1.1, 0.0))


def test_an_ideal_profile_stops_after_its_braking():
    assert stop_s(T, pulse()) == T[149]


def test_a_measured_profile_stops_although_its_noise_never_does():
    noise = np.random.default_rng(0).normal(0.0, 0.05, len(T))   # 1 % of the peak
    assert abs(stop_s(T, pulse() + noise) - 1.49) <= 0.01


def test_a_profile_without_motion_stopped_at_once():
    assert stop_s(T, np.zeros_like(T)) == 0.0

"""trajectories.csv: round trip, validation messages, error against truth."""

from pathlib import Path

import numpy as np
import pytest

from calibration.trajectories import ObjectPath, Trajectories, error_vs_truth
from wrapenv.config import InputError


def _paths() -> Trajectories:
    t = np.arange(5) / 20
    return Trajectories({"sled": ObjectPath(t, t * 0.1, -0.05 + 0 * t, 0 * t),
                         "L1C1R1": ObjectPath(t[1:], 0.3 + t[1:], 0.3 + 0 * t[1:], 0.01 * t[1:])})


def test_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "trajectories.csv"
    _paths().to_csv(path)
    assert path.read_text().splitlines()[0] == "t_s,object,x_m,z_m,angle_rad"
    back = Trajectories.from_csv(path)
    assert set(back.objects) == {"sled", "L1C1R1"}
    assert np.allclose(back.objects["L1C1R1"].x_m, _paths().objects["L1C1R1"].x_m, atol=1e-6)


def test_a_tumbling_body_s_unwrapped_angle_is_read(tmp_path: Path) -> None:
    """A bundle tumbling off the sled was tracked through 7.9 rad: `track` wrote it and
    `calibrate` refused it as degrees (2026-11-27)."""
    path = tmp_path / "tumbling.csv"
    path.write_text("t_s,object,x_m,z_m,angle_rad\n0,L2C1R1,2.02,-2.87,7.898178\n")
    assert Trajectories.from_csv(path).objects["L2C1R1"].angle_rad[0] == pytest.approx(7.898178)


@pytest.mark.parametrize("text,where", [
    ("t,object,x_m,z_m,angle_rad\n", "header"),
    ("t_s,object,x_m,z_m,angle_rad\n0,sled,1,2\n", "line 2"),
    ("t_s,object,x_m,z_m,angle_rad\n0,sled,abc,2,0\n", "line 2: x_m"),
    ("t_s,object,x_m,z_m,angle_rad\n0,sled,nan,2,0\n", "line 2: x_m"),
    ("t_s,object,x_m,z_m,angle_rad\n0,sled,0,0,0\n0,sled,0,0,0\n", "object sled"),
    ("t_s,object,x_m,z_m,angle_rad\n0, ,0,0,0\n", "line 2: object: empty name"),
    ("t_s,object,x_m,z_m,angle_rad\n", "no rows"),
    # another tracker's file in millimetres and degrees: the unit is named
    ("t_s,object,x_m,z_m,angle_rad\n0,pallet,-1250.0,72.0,0\n",
     r"line 2: x_m: -1250 m .*millimetres\? Positions are in metres"),
    ("t_s,object,x_m,z_m,angle_rad\n0,L2C1R1,0.1,0.6,45\n",
     r"line 2: angle_rad: 45 rad, more than two whole turns: degrees\?"),
])
def test_bad_files_name_the_place(tmp_path: Path, text: str, where: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=where):
        Trajectories.from_csv(path)


def test_error_vs_truth_ignores_start_offset() -> None:
    t = np.linspace(0, 1, 11)
    truth = {"a": ObjectPath(t, t, 0 * t, 0 * t)}
    tracked = Trajectories({"a": ObjectPath(t[2:], t[2:] + 0.5 + 0.001 * (t[2:] > 0.5),
                                            0 * t[2:], 0 * t[2:])})
    err = error_vs_truth(tracked, truth)["a"]
    assert err.frames == 9 and abs(err.offset_m - 0.5) < 1e-12
    assert abs(err.max_m - 0.001) < 1e-12 and 0 < err.rms_m < 0.001


def test_error_vs_truth_counts_vertical_motion_and_frames_within_the_truth_s_span() -> None:
    """A body 0.3 m up that truly drops 40 mm from 0.1 s to 1 s, tracked 3 mm to the side and
    4 mm high at 0.1 s (5 mm: the offset, not an error) and dropping 30 mm: 10 mm short at the
    end. The frame tracked at 0 s, before the truth starts, is not compared."""
    t = np.linspace(0.0, 1.0, 11)
    drop = (t - 0.1) / 0.9
    truth = {"a": ObjectPath(t[1:], 0 * t[1:], 0.3 - 0.04 * drop[1:], 0 * t[1:])}
    tracked = Trajectories({"a": ObjectPath(t, 0.003 + 0 * t, 0.304 - 0.03 * drop, 0 * t)})
    err = error_vs_truth(tracked, truth)["a"]
    assert err.frames == 10
    assert err.offset_m == pytest.approx(0.005)
    assert err.max_m == pytest.approx(0.01)
    assert error_vs_truth(tracked, {"b": truth["a"]}) == {}       # nothing to compare

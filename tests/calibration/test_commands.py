"""`wrapbench synth` and `wrapbench track` as a user runs them: exit status, what is written,
one-line errors and nothing half-written."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from recommender.cli import main
from wrapenv.load import LoadUnit


@pytest.fixture
def load_path(tmp_path: Path, small_load: LoadUnit) -> Path:
    path = tmp_path / "load.toml"
    path.write_text(small_load.to_toml())
    return path


def _one_line_error(capsys: pytest.CaptureFixture, *needles: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    for needle in needles:
        assert needle in err[0], err[0]
    return err[0]


def test_synth_then_track_writes_a_recording_and_its_trajectories(tmp_path, load_path, capsys):
    rec = tmp_path / "rec"
    assert main(["synth", str(load_path), "--out", str(rec), "--size", "400x250", "--level",
                 "0.2", "--fps", "10", "--seed", "1"]) == 0
    assert "400x250" in capsys.readouterr().out
    assert {p.name for p in rec.iterdir()} >= {"video.avi", "profile.csv", "setup.toml",
                                               "load.toml", "truth.json", "template.png"}
    out = tmp_path / "paths.csv"
    assert main(["track", str(rec), "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "error against truth.json" in stdout
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["t_s", "object", "x_m", "z_m", "angle_rad"]
    assert {r["object"] for r in rows} >= {"sled", "pallet", "L1C1R1", "L2C2R1"}


def test_track_writes_into_the_recording_by_default(recording_dir, tmp_path, capsys):
    rec = tmp_path / "rec"
    shutil.copytree(recording_dir, rec)
    assert main(["track", str(rec)]) == 0
    assert (rec / "trajectories.csv").exists()


@pytest.mark.parametrize("args, needles", [
    (["--size", "10x10"], ["size", ">= 64"]),
    (["--fps", "0"], ["fps"]),
    (["--friction-jitter", "1.5"], ["friction_jitter"]),
    (["--stiffness-scale", "nan"], ["--stiffness-scale"]),
    (["--level", "3"], ["level_g", "1.019"]),
])
def test_synth_rejects_bad_arguments_and_writes_nothing(args, needles, tmp_path, load_path,
                                                        capsys):
    out = tmp_path / "rec"
    assert main(["synth", str(load_path), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert all(n in err[-1] for n in needles), err
    assert not out.exists()


def test_synth_refuses_a_folder_that_holds_files(tmp_path, load_path, capsys):
    out = tmp_path / "rec"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert main(["synth", str(load_path), "--out", str(out)]) == 2
    _one_line_error(capsys, str(out), "not an empty folder")
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_track_of_a_missing_folder_is_an_input_error(tmp_path, capsys):
    assert main(["track", str(tmp_path / "nowhere")]) == 2
    _one_line_error(capsys, "nowhere")


def test_track_of_a_corrupt_video_writes_nothing(recording_dir, tmp_path, capsys):
    rec = tmp_path / "rec"
    shutil.copytree(recording_dir, rec)
    (rec / "video.avi").write_bytes(b"RIFF\0\0\0\0AVI garbage" * 10)
    out = tmp_path / "paths.csv"
    assert main(["track", str(rec), "--out", str(out)]) == 2
    _one_line_error(capsys, "video.avi")
    assert not out.exists() and not (rec / "trajectories.csv").exists()


def test_track_into_a_missing_folder_is_refused_before_tracking(recording_dir, tmp_path, capsys):
    assert main(["track", str(recording_dir), "--out", str(tmp_path / "no" / "t.csv")]) == 2
    _one_line_error(capsys, "--out", "does not exist")

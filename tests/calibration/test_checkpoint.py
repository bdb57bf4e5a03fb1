"""A fit keeps its search's replays as data and resumes from them: the resumed fit writes what
the uninterrupted one writes, without simulating again what the checkpoint holds."""

from __future__ import annotations

import dataclasses
import json
import shutil

import numpy as np
import pytest

import calibration.fit
from calibration.checkpoint import CHECKPOINT_FORMAT, FORMAT_FAMILY, ReplayLog, recording_key
from calibration.recording import Recording, Truth
from calibration.replay import observe
from calibration.trajectories import ObjectPath, Trajectories
from recommender.cli import main
from tests.calibration.conftest import SLIDE_BUDGET
from tests.cli import one_line
from wrapenv import __version__
from wrapenv.bench import SimSettings
from wrapenv.config import InputError
from wrapenv.load import Friction, FrictionPair

FRICTION = Friction(pallet_bundle=FrictionPair(0.37, 0.30))


@pytest.fixture(scope="module")
def slide_obs(slide_dir):
    truth = Truth.read(slide_dir)
    paths = Trajectories({k: ObjectPath(*(np.asarray(a) for a in (v.t_s, v.x_m, v.z_m,
                                                                   v.angle_rad)))
                          for k, v in truth.objects.items()})
    return observe(Recording.read(slide_dir), paths)


def test_a_replay_reads_back_bit_for_bit_and_an_unphysical_one_as_none(slide_obs, tmp_path):
    path = tmp_path / "fit.checkpoint.jsonl"
    residuals = np.array([0.1, -1 / 3, 2e-17, 123.456789012345678])
    with ReplayLog(path, [slide_obs], resume=False) as log:
        key = log.key(slide_obs, FRICTION, {}, SimSettings())
        other = log.key(slide_obs, FRICTION, {"stiffness": 1.5}, SimSettings())
        log.add(key, residuals)
        log.add(other, None)
    with ReplayLog(path, [slide_obs], resume=True) as log:
        held, got = log.get(key)
        assert held and got is not None and got.tobytes() == residuals.tobytes()
        assert log.get(other) == (True, None)
        # a replay given anything else is another replay
        assert log.get(log.key(slide_obs, FRICTION, {}, SimSettings(timestep_s=1 / 200))) \
            == (False, None)
        assert log.reused == 2


def test_a_line_cut_off_mid_write_is_ignored(slide_obs, tmp_path):
    path = tmp_path / "c.jsonl"
    with ReplayLog(path, [slide_obs], resume=False) as log:
        key = log.key(slide_obs, FRICTION, {}, SimSettings())
        log.add(key, np.ones(3))
    with path.open("a") as f:
        f.write('{"replay": "ab')        # killed while writing the next line
    with ReplayLog(path, [slide_obs], resume=True) as log:
        assert log.get(key)[0]


@pytest.mark.parametrize("line, field", [
    ("not json", "line 2"),
    ("[1.0, 2.0]", "line 2"),
    ('{"replay": "nope", "residuals": [1.0]}', "line 2.replay"),
    ('{"replay": "' + "a" * 64 + '", "residuals": [1.0, NaN]}', "line 2.residuals"),
    ('{"replay": "' + "a" * 64 + '", "residuals": ["1"]}', "line 2.residuals"),
    ('{"replay": "' + "a" * 64 + '", "residuals": []}', "line 2.residuals"),
])
def test_a_line_the_fit_never_writes_is_refused_naming_it(line, field, slide_obs, tmp_path):
    path = tmp_path / "c.jsonl"
    ReplayLog(path, [slide_obs], resume=False).close()
    with path.open("a") as f:
        f.write(line + "\n")
    with pytest.raises(InputError, match=field.replace(".", r"\.")):
        ReplayLog(path, [slide_obs], resume=True)


def test_a_take_s_key_names_the_levels_its_unit_ran_before_it(slide_obs):
    """The same frames of a unit that ran 0.2 g first replay otherwise: their replays are not
    those of the fresh take."""
    carried = dataclasses.replace(slide_obs, levels_before_g=(0.2,))
    assert recording_key(carried) != recording_key(slide_obs)
    assert recording_key(carried) != recording_key(
        dataclasses.replace(slide_obs, levels_before_g=(0.3,)))


def test_a_checkpoint_of_other_recordings_or_another_version_or_none_is_refused(slide_obs,
                                                                              tmp_path):
    path = tmp_path / "c.jsonl"
    path.write_text(json.dumps({"format": CHECKPOINT_FORMAT, "wrapbench_version": __version__,
                                "recordings": ["0" * 64]}) + "\n")
    with pytest.raises(InputError, match="other recordings"):
        ReplayLog(path, [slide_obs], resume=True)
    ReplayLog(path, [slide_obs], resume=False).close()
    head = json.loads(path.read_text()) | {"wrapbench_version": "0.0.1"}
    path.write_text(json.dumps(head) + "\n")
    with pytest.raises(InputError, match="wrapbench_version: written by wrapbench 0.0.1"):
        ReplayLog(path, [slide_obs], resume=True)
    path.write_text(json.dumps({"format": "wrapbench-search/2"}) + "\n")
    with pytest.raises(InputError, match="not a wrapbench calibration checkpoint"):
        ReplayLog(path, [slide_obs], resume=True)
    # version 1's replays ran a fit's values and gave residuals unrounded (`CHECKPOINT_FORMAT`)
    path.write_text(json.dumps(head | {"format": FORMAT_FAMILY + "1",
                                       "wrapbench_version": __version__}) + "\n")
    with pytest.raises(InputError, match="format: not a wrapbench calibration checkpoint of "
                                         "this version"):
        ReplayLog(path, [slide_obs], resume=True)
    with pytest.raises(InputError, match="no checkpoint to resume from"):
        ReplayLog(tmp_path / "none.jsonl", [slide_obs], resume=True)


@pytest.mark.parametrize("content, field, says", [
    (b"", "line 1", "empty"),
    (b'{"format": "wrapbench-calibration', "line 1", "empty"),   # its head cut off mid-write
    (b"\xff\xfe binary\n", "", "cannot read the checkpoint"),
    (b"format: wrapbench\n", "line 1", "malformed JSON"),
], ids=["empty", "head cut off", "not text", "head not JSON"])
def test_a_checkpoint_without_a_whole_head_line_is_refused(content, field, says, slide_obs,
                                                           tmp_path, assert_input_error):
    path = tmp_path / "c.jsonl"
    path.write_bytes(content)
    with pytest.raises(InputError, match=says) as err:
        ReplayLog(path, [slide_obs], resume=True)
    assert_input_error(err.value, str(path), field)


def _stopping_after(simulations: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The next fit is interrupted (as by Ctrl-C) once `simulations` have been spent."""
    real = calibration.fit.fit

    def interrupted(observations, settings, listener, log):
        def listen(n: int) -> None:
            listener(n)
            if n >= simulations:
                raise KeyboardInterrupt
        return real(observations, settings, listen, log)

    monkeypatch.setattr(calibration.fit, "fit", interrupted)


def test_an_interrupted_calibration_resumes_to_the_cal_json_of_an_uninterrupted_one(
        slide_dir, tmp_path, capsys, monkeypatch):
    rec = tmp_path / "rec"
    shutil.copytree(slide_dir, rec)
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    whole.mkdir()
    parts.mkdir()
    args = [str(rec), "--budget", str(SLIDE_BUDGET), "--workers", "1"]
    assert main(["calibrate", *args, "--out", str(whole / "cal.json")]) == 0
    assert not (whole / "cal.checkpoint.jsonl").exists()   # removed once the fit is written
    capsys.readouterr()

    _stopping_after(8, monkeypatch)
    assert main(["calibrate", *args, "--out", str(parts / "cal.json")]) == 130
    line = one_line(capsys.readouterr().err, warnings_aside=True)
    assert "nothing written" in line and "--resume" in line
    checkpoint = parts / "cal.checkpoint.jsonl"
    kept = checkpoint.read_text().splitlines()
    assert not (parts / "cal.json").exists() and len(kept) > 8   # the header and the replays

    monkeypatch.undo()
    assert main(["calibrate", *args, "--out", str(parts / "cal.json"), "--resume"]) == 0
    out = capsys.readouterr().out
    assert f"{len(kept) - 1} replays from the checkpoint" in out
    assert not checkpoint.exists()
    resumed, uninterrupted = (json.loads((d / "cal.json").read_text()) for d in (parts, whole))
    assert resumed == uninterrupted


def test_resume_without_a_checkpoint_is_refused_before_fitting(slide_dir, tmp_path, capsys):
    assert main(["calibrate", str(slide_dir), "--out", str(tmp_path / "cal.json"),
                 "--resume"]) == 2
    line = one_line(capsys.readouterr().err)
    assert "cal.checkpoint.jsonl" in line and "--resume" in line


def test_a_checkpoint_path_holding_a_user_s_file_is_refused_before_fitting(slide_dir, tmp_path,
                                                                         capsys):
    """The fit would append its replays to it, then remove it once it answered."""
    notes = tmp_path / "notes.txt"
    notes.write_text("my lab notes\n")
    assert main(["calibrate", str(slide_dir), "--out", str(tmp_path / "cal.json"),
                 "--checkpoint", str(notes)]) == 2
    line = one_line(capsys.readouterr().err)
    assert "notes.txt" in line and "not a wrapbench checkpoint" in line
    assert notes.read_text() == "my lab notes\n" and not (tmp_path / "cal.json").exists()

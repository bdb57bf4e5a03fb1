"""Synthetic recordings (calibration/synth.py): the folder reads back, the truth is where the
frames show the objects, the sled moves as its profile says, markers are detectable, and the same
seed gives the same recording."""

from __future__ import annotations

import fcntl
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from calibration.recording import Recording, Truth
from calibration.synth import MIN_MARKER_PX, STAGING_SUFFIX, marker_warning, synthesize
from wrapenv.config import InputError

ROW1 = {"L1C1R1", "L1C2R1", "L2C1R1", "L2C2R1"}


def detect(frame: np.ndarray, rec: Recording) -> dict[int, np.ndarray]:
    """Marker id -> corners (4, 2), refined to sub-pixel."""
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    assert rec.markers is not None
    detector = cv2.aruco.ArucoDetector(rec.markers.aruco(), params)
    corners, ids, _ = detector.detectMarkers(cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY))
    return {} if ids is None else {int(i): c.reshape(4, 2) for i, c in zip(ids.ravel(), corners,
                                                                            strict=True)}


def test_recording_reads_back_with_truth_for_every_object(recording_dir, frames_of):
    rec = Recording.read(recording_dir)
    truth = Truth.read(recording_dir)
    assert set(truth.objects) == {"sled", "pallet"} | ROW1
    frames = frames_of(rec.video)
    t = truth.objects["sled"].t_s
    assert len(frames) == len(t)
    np.testing.assert_allclose(t, np.arange(len(t)) / rec.fps)
    assert rec.profile.t_s[0] == 0.0 and rec.profile.t_s[-1] >= t[-1]
    np.testing.assert_allclose(truth.objects["sled"].x_m, rec.profile.position_m(t))
    assert truth.params["level_g"] == 0.2 and truth.params["seed"] == 3
    assert set(truth.params["friction"]) == {"sled_pallet", "pallet_bundle", "bundle_bundle"}
    # the pre-roll stands still, then the sled travels about a metre at 0.2 g
    assert truth.objects["sled"].x_m[0] == 0.0 and truth.objects["sled"].x_m[-1] > 0.5


def test_truth_centres_are_on_their_bundles(recording_dir, frames_of):
    """The template (the front of a bundle) matches each row-1 bundle where its truth centre
    projects, in the first frame and in one in full motion."""
    rec = Recording.read(recording_dir)
    truth = Truth.read(recording_dir)
    frames = frames_of(rec.video)
    height, width = frames[0].shape[:2]
    cam = rec.camera(width, height)
    template = cv2.cvtColor(cv2.imread(str(rec.template)), cv2.COLOR_BGR2GRAY)
    th, tw = template.shape
    speed = np.abs(np.gradient(truth.objects["sled"].x_m))
    for i in (0, int(np.argmax(speed))):
        gray = cv2.cvtColor(frames[i], cv2.COLOR_RGB2GRAY)
        for name in ROW1:
            track = truth.objects[name]
            u, v = cam.project([[track.x_m[i], 0.0, track.z_m[i]]])[0]
            x0, y0 = round(u - tw / 2) - 6, round(v - th / 2) - 6
            window = gray[y0:y0 + th + 12, x0:x0 + tw + 12]
            score = cv2.matchTemplate(window, template, cv2.TM_CCOEFF_NORMED)
            _, best, _, (bx, by) = cv2.minMaxLoc(score)
            found = (x0 + bx + (tw - 1) / 2, y0 + by + (th - 1) / 2)
            assert best > 0.7, (name, i, best)
            assert abs(found[0] - u) <= 1.5 and abs(found[1] - v) <= 1.5, (name, i, found, u, v)


def test_pallet_at_rest_projects_by_the_contract_mapping(recording_dir, frames_of):
    """At t = 0 the pallet's wood spans pixels centred where u = u0 + px_per_m x puts it."""
    rec = Recording.read(recording_dir)
    truth = Truth.read(recording_dir)
    frame = frames_of(rec.video)[0].astype(int)
    pallet = truth.objects["pallet"]
    length, height = rec.load.pallet.length_m, rec.load.pallet.height_m
    u0, v0 = rec.origin_px
    row = round(v0 - rec.px_per_m * (height - 0.011))  # through the top deck board
    wood = np.flatnonzero(frame[row, :, 0] - frame[row, :, 2] > 40)
    centre = (wood.min() + wood.max()) / 2
    assert abs(centre - (u0 + rec.px_per_m * pallet.x_m[0])) <= 1.0
    assert (wood.max() - wood.min() + 1) == pytest.approx(length * rec.px_per_m, abs=2)
    assert pallet.z_m[0] == pytest.approx(height / 2, abs=1e-3)


def test_sled_marker_moves_as_the_profile_says(recording_dir, frames_of):
    rec = Recording.read(recording_dir)
    frames = frames_of(rec.video)
    first, last = detect(frames[0], rec), detect(frames[-1], rec)
    assert 0 in first and 0 in last
    t_last = (len(frames) - 1) / rec.fps
    moved_m = (last[0][:, 0].mean() - first[0][:, 0].mean()) / rec.px_per_m
    expected = rec.profile.position_m(t_last) - rec.profile.position_m(0.0)
    # 0.5 px at this scale (~2 mm at 240 px/m; the 2 mm of a 1920 px recording is ~0.7 px)
    assert moved_m == pytest.approx(expected, abs=0.5 / rec.px_per_m)
    placement = rec.markers.placements[0]
    height, width = frames[0].shape[:2]
    u, v = rec.camera(width, height).project([[placement.offset_m[0], 0.0,
                                              -0.05 + placement.offset_m[1]]])[0]
    centre = first[0].mean(axis=0)
    assert abs(centre[0] - u) <= 0.5 and abs(centre[1] - v) <= 0.5


def test_wrapped_recording_shows_every_marker(wrapped_dir, frames_of):
    rec = Recording.read(wrapped_dir)
    frames = frames_of(rec.video)
    ids = {p.id for p in rec.markers.placements}
    objects = {p.object for p in rec.markers.placements}
    assert objects == {"sled", "pallet", "L1C1R1", "L1C2R1", "L2C1R1", "L2C2R1"}
    assert ids <= set(detect(frames[0], rec))
    truth = Truth.read(wrapped_dir)
    assert truth.params["wrap"] == {"material": "kraft", "stiffness_scale": 1.0,
                                    "tension_scale": 1.0}


def test_same_seed_same_recording(tmp_path, quarter_pallet_load):
    """Truth and frames are identical (byte for byte: the encoder is deterministic too);
    another seed changes the textures, not the physics."""
    args = {"level_g": 0.1, "size": (320, 200), "fps": 5.0, "pre_roll_s": 0.2}
    a = synthesize(quarter_pallet_load, tmp_path / "a", seed=11, **args)
    b = synthesize(quarter_pallet_load, tmp_path / "b", seed=11, **args)
    c = synthesize(quarter_pallet_load, tmp_path / "c", seed=12, **args)
    assert (a.folder / "truth.json").read_bytes() == (b.folder / "truth.json").read_bytes()
    assert a.video.read_bytes() == b.video.read_bytes()
    assert a.video.read_bytes() != c.video.read_bytes()
    ta, tc = Truth.read(a.folder), Truth.read(c.folder)
    np.testing.assert_array_equal(ta.objects["pallet"].x_m, tc.objects["pallet"].x_m)


def test_friction_jitter_changes_the_true_friction_only(tmp_path, quarter_pallet_load):
    rec = synthesize(quarter_pallet_load, tmp_path / "j", seed=5, friction_jitter=0.2, level_g=0.1,
                     size=(320, 200), fps=5.0, pre_roll_s=0.0)
    true = Truth.read(rec.folder).params["friction"]
    nominal = quarter_pallet_load.friction.sled_pallet
    assert true["sled_pallet"]["static"] != nominal.static
    assert 0.8 <= true["sled_pallet"]["static"] / nominal.static <= 1.2
    # load.toml says what was given, truth what was simulated
    assert rec.load == quarter_pallet_load


def test_a_take_after_earlier_levels_says_so_and_starts_where_they_left_the_unit(
        tmp_path, quarter_pallet_load):
    """A lab films one unit level after level: a take at 0.1 g after 0.3 g, at which the small
    unit's top layer slides 0.13 m back, starts with it there; setup.toml and the truth say
    which levels came before."""
    fresh = synthesize(quarter_pallet_load, tmp_path / "fresh", **TINY)
    after = synthesize(quarter_pallet_load, tmp_path / "after", levels_before_g=(0.3,), **TINY)
    assert (fresh.levels_before_g, after.levels_before_g) == ((), (0.3,))
    assert Truth.read(after.folder).params["levels_before_g"] == [0.3]
    start = {name: Truth.read(rec.folder).objects["L2C2R1"].x_m[0] for name, rec in
             (("fresh", fresh), ("after", after))}
    assert start["fresh"] - start["after"] > 0.1


def test_refuses_a_folder_in_use(tmp_path, quarter_pallet_load, assert_input_error):
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "x").write_text("")
    with pytest.raises(InputError) as err:
        synthesize(quarter_pallet_load, tmp_path / "busy", level_g=0.1, size=(320, 200))
    assert_input_error(err.value, str(tmp_path / "busy"), "")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["busy"]  # no temporary left


@pytest.mark.parametrize("argument, value", [
    ("pre_roll_s", -0.5), ("pre_roll_s", math.inf), ("marker_size_m", 0.0),
    ("marker_size_m", 0.2),   # wider than the sled's 0.1 m side
])
def test_refuses_arguments_out_of_range_before_simulating(argument, value, tmp_path,
                                                           quarter_pallet_load,
                                                           assert_input_error):
    with pytest.raises(InputError) as err:
        synthesize(quarter_pallet_load, tmp_path / "rec", level_g=0.1, size=(320, 200),
                   **{argument: value})
    assert_input_error(err.value, "arguments", argument)
    assert not (tmp_path / "rec").exists()


TINY = {"level_g": 0.1, "size": (320, 200), "fps": 5.0, "pre_roll_s": 0.0}


def test_stale_staging_folders_are_cleaned_live_ones_kept(tmp_path, quarter_pallet_load):
    """A run killed (SIGKILL) leaves its hidden staging folder; the next run in that folder
    removes it, but not the staging folder of a run still going (it holds a lock on it), nor
    other hidden folders."""
    stale = tmp_path / f".old.x1{STAGING_SUFFIX}"
    live = tmp_path / f".busy.x2{STAGING_SUFFIX}"
    mine = tmp_path / ".config"
    for folder in (stale, live, mine):
        folder.mkdir()
        (folder / "video.avi").write_bytes(b"partial")
    fd = os.open(live, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        synthesize(quarter_pallet_load, tmp_path / "rec", **TINY)
    finally:
        os.close(fd)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, mine.name, "rec"])


def test_sigterm_leaves_no_staging_folder(tmp_path, quarter_pallet_load):
    """SIGTERM during the encoding (the staging folder exists) unwinds like Ctrl-C: exit 143
    (128 + SIGTERM), one line, no recording and no hidden folder."""
    load = tmp_path / "load.toml"
    load.write_text(quarter_pallet_load.to_toml())
    out = tmp_path / "runs" / "rec"
    proc = subprocess.Popen([sys.executable, "-m", "recommender.cli", "synth", str(load),
                             "--out", str(out), "--size", "640x400", "--fps", "40"],
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(Path.cwd())})
    deadline = time.monotonic() + 120
    while not any((tmp_path / "runs").glob(f".rec.*{STAGING_SUFFIX}")):
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read()
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.strip().splitlines() == ["wrapbench synth: interrupted, nothing written"]
    assert list((tmp_path / "runs").iterdir()) == []


def test_a_recording_that_does_not_read_back_leaves_nothing(tmp_path, quarter_pallet_load,
                                                             monkeypatch):
    """The read-back check runs before the folder is put in place: a video at another rate
    than setup.toml's (as the container's whole rates made of --fps 29.97) used to leave the
    whole folder behind, which blocked the rerun."""
    from calibration import synth

    write_video = synth.write_video
    monkeypatch.setattr(synth, "write_video",
                        lambda path, frames, fps, size: write_video(path, frames, fps + 1, size))
    with pytest.raises(InputError, match="recording.fps"):
        synthesize(quarter_pallet_load, tmp_path / "rec", **TINY)
    assert list(tmp_path.iterdir()) == []


def test_progress_is_reported_per_frame(tmp_path, quarter_pallet_load):
    calls = []
    rec = synthesize(quarter_pallet_load, tmp_path / "rec",
                     progress=lambda k, n: calls.append((k, n)), **TINY)
    frames = len(Truth.read(rec.folder).objects["sled"].t_s)
    assert calls == [(k, frames) for k in range(1, frames + 1)]


def test_markers_big_enough_for_track_get_no_warning_and_small_ones_the_size_that_would_do(
        recording_dir):
    """The warning's size scales the image by the markers' shortfall: 7.5 px markers in a
    320 x 200 image would be 15 px in 640 x 400."""
    rec = Recording.read(recording_dir)
    assert rec.markers is not None and rec.markers.size_m is not None
    side_px = rec.markers.size_m * rec.px_per_m
    assert side_px >= MIN_MARKER_PX  # the fixture's recording: tracked in every test
    small = replace(rec, px_per_m=7.5 / rec.markers.size_m)
    assert marker_warning(rec, (800, 500)) == ""
    warning = marker_warning(small, (320, 200))
    assert warning.startswith("the markers are 7.5 px")
    assert warning.endswith("record at --size 640x400 or larger")
    assert marker_warning(small, (2400, 1500)).endswith("no size up to 4096 px makes them that "
                                                         "large")

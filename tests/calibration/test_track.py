"""`track` on small synthetic recordings: accuracy against truth.json, identities, and the
errors and warnings bad input gets.

Accuracy goals are the issue's (2 mm RMS, 6 mm max at 1920x1200) scaled to the smaller image's
px_per_m: the tracker works in pixels, so its error in metres grows as pixels get bigger.
"""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from calibration.filming import write_video
from calibration.recording import Recording, SledProfile, Truth
from calibration.synth import synthesize
from calibration.track import track
from calibration.trajectories import Trajectories, error_vs_truth
from calibration.vision.debug_video import DebugVideo
from calibration.vision.roi import PixelMap
from wrapenv.config import InputError
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

SIZE = (640, 400)
#: The goal's px_per_m at 1920x1200 (the synthetic camera fits the test in the image).
FULL_PX_PER_M = 400.0


@pytest.fixture(scope="module")
def two_layer(tmp_path_factory: pytest.TempPathFactory) -> Recording:
    return synthesize(LoadUnit.from_toml("examples/pet_2layer_columnar.toml"),
                      tmp_path_factory.mktemp("rec") / "two", level_g=0.4, size=SIZE)


def _check_accuracy(rec: Recording, result_objects: Trajectories) -> None:
    scale = FULL_PX_PER_M / rec.px_per_m
    truth = Truth.read(rec.folder).objects
    errors = error_vs_truth(result_objects, truth)
    assert set(errors) == set(result_objects.objects)
    for name, e in errors.items():
        assert e.rms_m < 2e-3 * scale, name
        assert e.max_m < 6e-3 * scale, name  # also rules out swaps: neighbours are 0.28 m apart
        assert e.offset_m < 6e-3 * scale, name


def test_two_layer_unwrapped(two_layer: Recording, tmp_path: Path) -> None:
    result = track(two_layer, debug_video=tmp_path / "debug.mp4")
    names = set(result.trajectories.objects)
    assert names == {"sled", "pallet"} | {f"L{k}C{c}R1" for k in (1, 2) for c in (1, 2, 3, 4)}
    _check_accuracy(two_layer, result.trajectories)
    # at 640x400 the sled's 6 cm markers are 7 px wide, too small for ArUco: that is all
    assert [w for w in result.warnings if not w.startswith("sled markers not found")] == []
    video = (tmp_path / "debug.mp4").stat()
    assert video.st_size > 0
    umask = os.umask(0)
    os.umask(umask)
    assert video.st_mode & 0o777 == 0o666 & ~umask    # an ordinary file, like the CSV
    out = tmp_path / "trajectories.csv"
    result.trajectories.to_csv(out)
    assert set(Trajectories.from_csv(out).objects) == names


def test_three_layer_tipping(tmp_path: Path) -> None:
    rec = synthesize(LoadUnit.from_toml("examples/pet_3layer_columnar.toml"), tmp_path / "three",
                     level_g=0.3, size=SIZE)
    result = track(rec)
    assert len(result.trajectories.objects) == 2 + 12
    _check_accuracy(rec, result.trajectories)


def test_wrapped_follows_markers(tmp_path: Path) -> None:
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    wrap = WrapFormat.from_toml("examples/wrap_kraft_2layer.toml", load.layout().load_height_m)
    # ArUco needs ~15 px markers: 1280x800 and the largest markers the sled's side takes
    rec = synthesize(load, tmp_path / "wrapped", wrap=wrap, level_g=0.4, size=(1280, 800),
                     marker_size_m=0.075)
    result = track(rec)
    assert {"sled", "pallet", "L1C1R1", "L1C4R1", "L2C1R1", "L2C4R1"} <= set(
        result.trajectories.objects)
    _check_accuracy(rec, result.trajectories)


def test_wrapped_small_follows_marker_patches(wrapped_dir: Path) -> None:
    """800x500 (240 px/m), 18 px markers: every carrying object followed in every frame."""
    rec = Recording.read(wrapped_dir)
    result = track(rec)
    assert set(result.trajectories.objects) == {"sled", "pallet", "L1C1R1", "L1C2R1", "L2C1R1",
                                                "L2C2R1"}
    _check_accuracy(rec, result.trajectories)
    assert result.warnings == []


NO_SIZE_WARNING = ("setup.toml gives no markers.size_m: the markers' sides cannot cross-check "
                   "the scale (camera.px_per_m)")


def test_debug_video_of_a_wrapped_unit_draws_every_object_where_tracked(
        wrapped_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each frame shows every object of that frame's CSV rows at its tracked centre: the
    objects followed through markers (pallet and bundles) used to be left out."""
    drawn: dict[int, dict[str, tuple[float, float]]] = {}

    def draw(self, bgr, index, objects, poses) -> None:
        drawn[index] = {o.name: (poses[o.name].u, poses[o.name].v)
                        for o in objects if o.name in poses}

    monkeypatch.setattr(DebugVideo, "draw", draw)
    rec = Recording.read(wrapped_dir)
    result = track(rec, debug_video=tmp_path / "debug.mp4")
    pixmap = PixelMap(rec.px_per_m, *rec.origin_px)
    for name, path in result.trajectories.objects.items():
        for t, x, z in zip(path.t_s, path.x_m, path.z_m, strict=True):
            centre = drawn[round(t * rec.fps)][name]
            assert centre == pytest.approx(pixmap.to_px(x, z), abs=1e-3), (name, t)
    assert {len(names) for names in drawn.values()} == {6}


@pytest.mark.parametrize("marker_size", [True, False], ids=["size_m", "no size_m"])
def test_scale_check_on_the_sled_markers(marker_size: bool, recording_dir: Path,
                                         tmp_path: Path) -> None:
    """The distance between the sled's markers agrees with setup.toml's scale; 3 % off warns.
    The distance comes from their placements: markers.size_m is not needed (without it a
    warning says the markers' sides cannot check the scale too)."""
    folder = tmp_path / "scaled"
    shutil.copytree(recording_dir, folder)
    if not marker_size:
        _drop_marker_size(folder)
    warnings = track(Recording.read(folder)).warnings
    assert not any("px/m" in w for w in warnings)
    assert (NO_SIZE_WARNING in warnings) is not marker_size
    setup = folder / "setup.toml"
    setup.write_text(re.sub(r"px_per_m = ([0-9.]+)",
                            lambda m: f"px_per_m = {1.03 * float(m.group(1))!r}",
                            setup.read_text()))
    warnings = track(Recording.read(folder)).warnings
    assert any("px/m" in w and "(-2.9 %)" in w for w in warnings), warnings


def _drop_marker_size(folder: Path) -> None:
    setup = folder / "setup.toml"
    text, n = re.subn(r"size_m = [0-9.]+\n", "", setup.read_text())
    assert n == 1
    setup.write_text(text)


def test_wrapped_unit_without_marker_size(wrapped_dir: Path, tmp_path: Path) -> None:
    """Without setup.toml's markers.size_m the markers still name and locate every object:
    their boxes are sized from the corners ArUco finds, as accurately as from the size. The
    sides they cannot check the scale by are a warning (CONTRACTS.md)."""
    folder = tmp_path / "no-size"
    shutil.copytree(wrapped_dir, folder)
    _drop_marker_size(folder)
    rec = Recording.read(folder)
    assert rec.markers is not None and rec.markers.size_m is None
    result = track(rec)
    assert set(result.trajectories.objects) == {"sled", "pallet", "L1C1R1", "L1C2R1", "L2C1R1",
                                                "L2C2R1"}
    _check_accuracy(rec, result.trajectories)
    assert result.warnings == [NO_SIZE_WARNING]


def test_marker_size_off_the_scale_is_said_with_both_sides(recording_dir: Path,
                                                          tmp_path: Path) -> None:
    """markers.size_m of 0.05 m where 0.075 m markers were printed: their sides in the image
    disagree with size_m x px_per_m by a third, over the 20 % a side's blur cannot explain."""
    folder = tmp_path / "small-size"
    shutil.copytree(recording_dir, folder)
    setup = folder / "setup.toml"
    setup.write_text(setup.read_text().replace("size_m = 0.075", "size_m = 0.05"))
    rec = Recording.read(folder)
    (warning,) = track(rec).warnings
    expected = f"is {0.05 * rec.px_per_m:.1f} px, but ArUco measures the markers' sides "
    assert expected in warning, warning
    measured = re.search(r"sides ([0-9.]+) px in frame 0", warning)
    assert measured and float(measured[1]) == pytest.approx(0.075 * rec.px_per_m, rel=0.05)


def test_wrapped_unit_without_markers_on_its_bundles_says_no_layer_is_tracked(
        wrapped_dir: Path, tmp_path: Path) -> None:
    """The web hides the bundles: with markers on the sled and the pallet only, the run
    follows those two and says why no layer is among them (it used to say nothing)."""
    folder = tmp_path / "no-load-markers"
    shutil.copytree(wrapped_dir, folder)
    setup = folder / "setup.toml"
    head, *blocks = setup.read_text().split("[[markers.placement]]")
    kept = [b for b in blocks if 'object = "sled"' in b or 'object = "pallet"' in b]
    setup.write_text("[[markers.placement]]".join([head, *kept]))
    result = track(Recording.read(folder))
    assert set(result.trajectories.objects) == {"sled", "pallet"}
    assert result.warnings == ["the layers of a wrapped unit are followed only through "
                               "markers, and setup.toml places none on its bundles: no layer "
                               "is tracked"]


def test_scale_left_unchecked_is_said(recording_dir: Path, tmp_path: Path) -> None:
    """With one sled marker declared there is no distance to check the scale by: a warning,
    where the check used to be skipped silently."""
    folder = tmp_path / "one"
    shutil.copytree(recording_dir, folder)
    setup = folder / "setup.toml"
    blocks = setup.read_text().split("[[markers.placement]]")
    setup.write_text("[[markers.placement]]".join(blocks[:2]))
    warnings = track(Recording.read(folder)).warnings
    assert warnings == ["only one sled marker (0) seen in frame 0: setup.toml's camera.px_per_m "
                        "is not cross-checked"], warnings


def _copy(rec: Recording, tmp_path: Path) -> Path:
    folder = tmp_path / "copy"
    shutil.copytree(rec.folder, folder)
    return folder


@pytest.mark.parametrize("origin", ["[5000.0, 317.0]", "[-5000.0, -317.0]"])
def test_unit_outside_the_image_in_frame_0_names_the_camera_origin(
        origin: str, recording_dir: Path, tmp_path: Path, assert_input_error) -> None:
    """Nothing can be named where the camera shows none of the unit: bad input, not the
    traceback of an empty crop."""
    folder = tmp_path / "away"
    shutil.copytree(recording_dir, folder)
    setup = folder / "setup.toml"
    setup.write_text(re.sub(r"origin_px = \[.*\]", f"origin_px = {origin}", setup.read_text()))
    with pytest.raises(InputError) as err:
        track(Recording.read(folder))
    assert_input_error(err.value, str(setup), "camera.origin_px")


def _shift_origin(folder: Path, du_px: float, dv_px: float) -> tuple[float, float]:
    """setup.toml's camera.origin_px moved by (du, dv) pixels; the origin it had."""
    setup = folder / "setup.toml"
    u0, v0 = Recording.read(folder).origin_px
    setup.write_text(re.sub(r"origin_px = \[.*\]", f"origin_px = [{u0 + du_px}, {v0 + dv_px}]",
                            setup.read_text()))
    return u0, v0


@pytest.mark.parametrize("du_px, dv_px", [(20.0, 0.0), (0.0, -20.0)])
def test_origin_the_sled_markers_contradict_is_refused_with_the_one_they_agree_with(
        du_px: float, dv_px: float, recording_dir: Path, tmp_path: Path,
        assert_input_error) -> None:
    """20 px at 240 px/m: every absolute position would be 83 mm off (the sled ahead of or
    below where its profile and the camera put it). The markers name the origin that agrees:
    the one the recording was made with."""
    folder = tmp_path / "origin"
    shutil.copytree(recording_dir, folder)
    u0, v0 = _shift_origin(folder, du_px, dv_px)
    with pytest.raises(InputError) as err:
        track(Recording.read(folder))
    assert_input_error(err.value, str(folder / "setup.toml"), "camera.origin_px")
    assert _origin_that_agrees(str(err.value)) == pytest.approx((u0, v0), abs=1.0)


def _origin_that_agrees(text: str) -> tuple[float, float]:
    found = re.search(r"origin_px = \[(\S+), (\S+)\] would agree", text)
    assert found, text
    return float(found[1]), float(found[2])


def test_origin_a_few_pixels_off_is_a_warning(recording_dir: Path, tmp_path: Path) -> None:
    """6 px (25 mm): tracked, and said, with the origin that agrees."""
    folder = tmp_path / "origin"
    shutil.copytree(recording_dir, folder)
    u0, v0 = _shift_origin(folder, 6.0, 0.0)
    warnings = [w for w in track(Recording.read(folder)).warnings if "origin_px" in w]
    assert len(warnings) == 1 and warnings[0].startswith(
        "the sled's markers put the sled -25 mm along x"), warnings
    assert f"camera.origin_px [{u0 + 6.0}, {v0}] put it in frame 0" in warnings[0]
    assert _origin_that_agrees(warnings[0]) == pytest.approx((u0, v0), abs=1.0)


def _rewrite_video(video: Path, edit) -> None:
    """The video re-encoded as synth encodes it, its frames passed through `edit`."""
    cap = cv2.VideoCapture(str(video))
    fps = cap.get(cv2.CAP_PROP_FPS)
    frames = []
    while (got := cap.read())[0]:
        frames.append(cv2.cvtColor(got[1], cv2.COLOR_BGR2RGB))
    cap.release()
    frames = edit(frames)
    height, width = frames[0].shape[:2]
    write_video(video, frames, fps, (width, height))


@pytest.mark.parametrize("edit", [
    pytest.param(lambda frames: frames[:8] + frames[12:], id="4 frames lost inside"),
    pytest.param(lambda frames: [cv2.resize(f, None, fx=1.25, fy=1.25) for f in frames],
                 id="rescaled 1.25 x"),
])
def test_video_whose_sled_parts_from_the_profile_is_refused(
        edit, recording_dir: Path, tmp_path: Path, assert_input_error) -> None:
    """Frames lost inside a video stamp every later frame too early, a rescaled video makes
    every metre 1.25 m: tracked, either wrote paths decimetres to metres off, exit 0. The sled
    followed on the video against profile.csv's path shows it. A debug video asked for is
    not left behind: the recording was refused."""
    folder = tmp_path / "edited"
    shutil.copytree(recording_dir, folder)
    rec = Recording.read(folder)
    _rewrite_video(rec.video, edit)
    debug = tmp_path / "debug"
    debug.mkdir()
    with pytest.raises(InputError) as err:
        track(Recording.read(folder), debug_video=debug / "debug.mp4")
    assert_input_error(err.value, str(rec.video), "frames")
    assert "departs from profile.csv's path" in str(err.value)
    assert list(debug.iterdir()) == []


def test_unit_leaving_the_view_is_lost_there_with_one_warning(recording_dir: Path,
                                                              tmp_path: Path) -> None:
    """A profile that carries the sled 100 m away from 2 s on: every object is left out of
    the frames the unit is out of view in, and one warning names them."""
    folder = tmp_path / "leaves"
    shutil.copytree(recording_dir, folder)
    p = Recording.read(folder).profile
    away = SledProfile(p.t_s, p.accel_mps2, p.vel_mps, p.pos_m + 100.0 * (p.t_s > 1.95))
    (folder / "profile.csv").write_bytes(away.to_csv())
    frames = len(Truth.read(folder).objects["sled"].t_s)
    result = track(Recording.read(folder))
    assert [w.split(":")[0] for w in result.warnings] == [
        f"unit out of view in frames 20-{frames - 1}"], result.warnings
    for name, path in result.trajectories.objects.items():
        assert path.t_s[-1] == pytest.approx(1.9), name


def test_corrupt_video_is_an_input_error(two_layer: Recording, tmp_path: Path) -> None:
    folder = _copy(two_layer, tmp_path)
    rec = Recording.read(folder)
    rec.video.write_bytes(b"not a video")
    with pytest.raises(InputError, match=rec.video.name):
        track(rec)


def test_an_interrupted_run_leaves_no_debug_video(two_layer: Recording, tmp_path: Path) -> None:
    def interrupt(frame: int, frames: int) -> None:
        if frame == 5:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        track(two_layer, debug_video=tmp_path / "debug.mp4", progress=interrupt)
    assert list(tmp_path.iterdir()) == []


def test_truncated_video_loses_its_cut_frame_not_its_accuracy(two_layer: Recording,
                                                               tmp_path: Path) -> None:
    """A file cut three quarters through: the frame it was cut inside decodes half grey and
    was tracked 70 mm off; it is dropped, with a warning naming the frames kept."""
    folder = _copy(two_layer, tmp_path)
    video = folder / two_layer.video.name
    data = video.read_bytes()
    video.write_bytes(data[:len(data) * 3 // 4])
    rec = Recording.read(folder)
    result = track(rec)
    _check_accuracy(rec, result.trajectories)
    frames = len(result.trajectories.objects["sled"].t_s)
    assert 0 < frames < len(Truth.read(folder).objects["sled"].t_s) - 1
    cut = [w for w in result.warnings if w.startswith(video.name)]
    assert len(cut) == 1 and "cut short" in cut[0] and f"frames 0-{frames - 1}" in cut[0], cut


def test_a_layer_the_video_does_not_show_is_named(slide_dir: Path, tmp_path: Path) -> None:
    """load.toml says two layers, the video shows one: the second's bundles were followed over
    the background with a warning per bundle, none saying what is wrong."""
    folder = tmp_path / "two"
    shutil.copytree(slide_dir, folder)
    load = folder / "load.toml"
    load.write_text(re.sub(r"(?m)^layers = 1", "layers = 2", load.read_text()))
    warnings = track(Recording.read(folder)).warnings
    assert [w for w in warnings if w.startswith("layer ")] == [
        "layer 2: none of its bundles matches the template in frame 0, though a layer below "
        "does: does load.toml (stack.layers = 2, bundle.height_m = 0.33) describe the unit "
        "filmed?"]


def test_unmatched_template_names_the_file(two_layer: Recording, tmp_path: Path) -> None:
    folder = _copy(two_layer, tmp_path)
    rng = np.random.default_rng(0)
    cv2.imwrite(str(folder / "template.png"), rng.integers(0, 255, (40, 30), np.uint8))
    with pytest.raises(InputError, match="template.png"):
        track(Recording.read(folder))


def test_a_debug_video_opencv_cannot_write_is_refused_leaving_nothing(
        two_layer: Recording, tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"debug\.txt: OpenCV cannot write a video there"):
        track(two_layer, debug_video=tmp_path / "debug.txt")
    assert list(tmp_path.iterdir()) == []


def test_profile_shorter_than_video(two_layer: Recording, tmp_path: Path) -> None:
    p = two_layer.profile
    keep = p.t_s < 1.0
    short = SledProfile(p.t_s[keep], p.accel_mps2[keep], p.vel_mps[keep], p.pos_m[keep])
    with pytest.raises(InputError, match="profile.csv"):
        track(replace(two_layer, profile=short))


def test_fps_mismatch(two_layer: Recording) -> None:
    with pytest.raises(InputError, match="recording.fps"):
        track(replace(two_layer, fps=two_layer.fps * 1.5))


def test_a_lone_frame_found_between_lost_ones_is_left_out_as_lost():
    """A falling bundle's patch can score above the lost threshold for one frame on whatever it
    lands on; that frame's pose is not the bundle's (a recorded take: 284 mm off)."""
    from calibration.track import _Poses
    from calibration.vision.tracking import LOST_SCORE, Pose

    poses = _Poses({"L2C1R1": Pose(0.0, 0.0, 0.0), "L1C1R1": Pose(0.0, 0.0, 0.0)})
    good, bad = LOST_SCORE + 0.1, LOST_SCORE - 0.1
    scores = {1: good, 2: bad, 3: good, 4: bad, 5: bad, 6: good, 7: good}
    for index, score in scores.items():
        poses.record(index, {"L2C1R1": (Pose(float(index), 0.0, 0.0), score),
                             "L1C1R1": (Pose(float(index), 0.0, 0.0), good)})
    poses.drop_lone_finds()
    assert [i for i, _ in poses.found["L2C1R1"]] == [0, 1, 6, 7]   # frame 3 stood alone
    assert poses.lost["L2C1R1"] == [2, 3, 4, 5]
    assert [i for i, _ in poses.found["L1C1R1"]] == list(range(8)) and not poses.lost["L1C1R1"]

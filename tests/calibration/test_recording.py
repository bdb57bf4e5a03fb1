"""The recording folder (calibration/recording.py): reading a good folder, the sled profile, and
one `InputError` naming file and field for each way a folder can be wrong."""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from calibration.recording import Recording, SledProfile, Truth
from calibration.trajectories import ObjectPath, Trajectories
from wrapenv.config import InputError, read_toml


def test_reads_a_synthetic_recording(recording_dir, frames_of):
    rec = Recording.read(recording_dir)
    assert rec.video.name == "video.avi" and rec.fps == 10.0
    assert rec.px_per_m > 0 and len(rec.origin_px) == 2
    assert frames_of(rec.video)[0].shape[:2] == (500, 800)
    assert rec.wrap is None and rec.template == recording_dir / "template.png"
    assert rec.markers is not None and rec.markers.dictionary == "DICT_4X4_50"
    assert [p.object for p in rec.markers.placements] == ["sled", "sled"]
    cam = rec.camera(800, 500)
    assert cam.px_per_m == rec.px_per_m and cam.origin_px == rec.origin_px
    assert rec.load.stack.layers == 2


def test_profile_integrates_velocity_and_position_when_absent(tmp_path):
    t = np.linspace(0.0, 2.0, 401)
    path = tmp_path / "profile.csv"
    path.write_text("t_s,accel_mps2\n" + "".join(f"{float(v)!r},2.0\n" for v in t))
    profile = SledProfile.read(path)
    np.testing.assert_allclose(profile.vel_mps, 2.0 * t, atol=1e-12)
    np.testing.assert_allclose(profile.pos_m, t**2, atol=1e-4)
    assert profile.position_m(1.5) == pytest.approx(2.25, abs=1e-4)


def test_profile_position_comes_from_its_velocity_when_only_pos_m_is_absent(tmp_path):
    """A measured velocity is the better source of position than the acceleration: the sled
    here coasts at 1 m/s (vel_mps) while the accelerometer reads 0, so it travels t metres;
    it used to be integrated from the acceleration and stand still."""
    t = np.linspace(0.0, 2.0, 401)
    path = tmp_path / "profile.csv"
    path.write_text("t_s,accel_mps2,vel_mps\n" + "".join(f"{float(v)!r},0.0,1.0\n" for v in t))
    profile = SledProfile.read(path)
    np.testing.assert_array_equal(profile.vel_mps, np.ones_like(t))
    np.testing.assert_allclose(profile.pos_m, t, atol=1e-12)


def test_profile_round_trips_through_csv(tmp_path):
    t = np.array([0.0, 0.1, 0.25])
    profile = SledProfile(t, np.array([1.0, 2.0, 0.5]), np.array([0.0, 0.15, 0.34]),
                          np.array([0.0, 0.01, 0.05]))
    (tmp_path / "profile.csv").write_bytes(profile.to_csv())
    back = SledProfile.read(tmp_path / "profile.csv")
    for key in ("t_s", "accel_mps2", "vel_mps", "pos_m"):
        np.testing.assert_array_equal(getattr(back, key), getattr(profile, key))


def _edit(name: str, old: str, new: str) -> Callable[[Path], None]:
    def change(folder: Path) -> None:
        path = folder / name
        text = path.read_text()
        assert old in text, f"{old!r} not in {name}"
        path.write_text(text.replace(old, new, 1))
    return change


def _remove(name: str) -> Callable[[Path], None]:
    return lambda folder: (folder / name).unlink()


def _write(name: str, data: bytes) -> Callable[[Path], None]:
    def write(folder: Path) -> None:
        (folder / name).write_bytes(data)

    return write


def _empty_video(folder: Path) -> None:
    """A container with its header and no frame: the camera stopped before the test."""
    writer = cv2.VideoWriter(str(folder / "video.avi"), cv2.VideoWriter.fourcc(*"MJPG"), 10.0,
                             (800, 500))
    writer.release()


def _damage_first_frame(folder: Path) -> None:
    """The first frame's JPEG overwritten with zeros, the container's index intact."""
    path = folder / "video.avi"
    data = bytearray(path.read_bytes())
    start = data.find(b"\xff\xd8")
    end = data.find(b"\xff\xd9", start) + 2
    data[start:end] = bytes(end - start)
    path.write_bytes(data)


def _truncate_profile(folder: Path) -> None:
    path = folder / "profile.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[: len(lines) // 2]) + "\n")


def _nan_in_profile(folder: Path) -> None:
    path = folder / "profile.csv"
    lines = path.read_text().splitlines()
    t = lines[5].split(",")[0]
    lines[5] = f"{t},nan,0.0,0.0"
    path.write_text("\n".join(lines) + "\n")


def _profile_rows(change: Callable[[list[str]], list[str]]) -> Callable[[Path], None]:
    """Edit profile.csv's data rows (the header kept)."""
    def edit(folder: Path) -> None:
        path = folder / "profile.csv"
        header, *rows = path.read_text().splitlines()
        path.write_text("\n".join([header, *change(rows)]) + "\n")
    return edit


def _later(rows: list[str]) -> list[str]:
    """Every sample a second late: the profile starts after the video's first frame."""
    return [",".join([repr(float(r.split(",")[0]) + 1.0), *r.split(",")[1:]]) for r in rows]


def _px_per_m_times(factor: float) -> Callable[[Path], None]:
    """The camera's scale given in other units: per millimetre (1e-3) or per centimetre."""
    def change(folder: Path) -> None:
        path = folder / "setup.toml"
        lines = path.read_text().splitlines()
        lines = [f"px_per_m = {factor * float(line.split('=')[1])}"
                 if line.startswith("px_per_m =") else line for line in lines]
        path.write_text("\n".join(lines) + "\n")
    return change


def _placement_edit(index: int, key: str, value: str) -> Callable[[Path], None]:
    """Change one key of the index-th [[markers.placement]]."""
    def change(folder: Path) -> None:
        path = folder / "setup.toml"
        blocks = path.read_text().split("[[markers.placement]]")
        lines = blocks[index + 1].splitlines()
        lines = [f"{key} = {value}" if line.startswith(f"{key} =") else line for line in lines]
        blocks[index + 1] = "\n".join(lines) + "\n"
        path.write_text("[[markers.placement]]".join(blocks))
    return change


CASES = {
    "setup missing": (_remove("setup.toml"), "setup.toml", ""),
    "fps zero": (_edit("setup.toml", "fps = 10.0", "fps = 0"), "setup.toml", "recording.fps"),
    "fps not the video's": (_edit("setup.toml", "fps = 10.0", "fps = 25.0"), "setup.toml",
                            "recording.fps"),
    "px_per_m infinite": (_edit("setup.toml", "px_per_m = ", "px_per_m = inf #"), "setup.toml",
                          "camera.px_per_m"),
    # the pallet would span a fraction of a pixel, or 10 frames: a unit slip, named as such
    "px_per_m given per millimetre": (_px_per_m_times(1e-3), "setup.toml", "camera.px_per_m"),
    "px_per_m 100 x too large": (_px_per_m_times(100.0), "setup.toml", "camera.px_per_m"),
    "origin not finite": (_edit("setup.toml", "origin_px = [", "origin_px = [nan, "),
                          "setup.toml", "camera.origin_px"),
    "origin of three numbers": (_edit("setup.toml", "origin_px = [", "origin_px = [1.0, "),
                                "setup.toml", "camera.origin_px"),
    "camera missing": (_edit("setup.toml", "[camera]", "[kamera]"), "setup.toml", "camera"),
    "unknown dictionary": (_edit("setup.toml", "DICT_4X4_50", "DICT_4X4_51"), "setup.toml",
                           "markers.dictionary"),
    "marker size in millimetres": (_edit("setup.toml", "size_m = 0.075", "size_m = 75.0"),
                                   "setup.toml", "markers.size_m"),
    "duplicate marker id": (_placement_edit(1, "id", "0"), "setup.toml",
                            "markers.placement[1].id"),
    "id beyond dictionary": (_placement_edit(0, "id", "50"), "setup.toml",
                             "markers.placement[0].id"),
    "unknown object": (_placement_edit(0, "object", '"L9C1R1"'), "setup.toml",
                       "markers.placement[0].object"),
    "template missing": (_remove("template.png"), "setup.toml", "template"),
    "template not an image": (_write("template.png", b"not a picture"), "setup.toml",
                              "template"),
    "video missing": (_remove("video.avi"), "video.mp4", ""),
    "video unreadable": (_write("video.avi", b"RIFF not a video at all" * 100), "video.avi", ""),
    "video without a frame": (_empty_video, "video.avi", ""),
    "profile missing": (_remove("profile.csv"), "profile.csv", ""),
    "profile shorter than video": (_truncate_profile, "profile.csv", "t_s"),
    "profile NaN": (_nan_in_profile, "profile.csv", "accel_mps2"),
    "profile without accel": (_edit("profile.csv", "accel_mps2", "acc"), "profile.csv",
                              "accel_mps2"),
    "profile of one sample": (_profile_rows(lambda rows: rows[:1]), "profile.csv", "t_s"),
    "profile of its header only": (_profile_rows(lambda rows: []), "profile.csv", "t_s"),
    "profile out of time order": (_profile_rows(lambda rows: [rows[1], rows[0], *rows[2:]]),
                                  "profile.csv", "t_s"),
    "profile with a word for a number": (_profile_rows(lambda rows: [
        rows[0], "0.05,fast,0,0", *rows[2:]]), "profile.csv", "line 3"),
    "profile starting after the first frame": (_profile_rows(_later), "profile.csv", "t_s"),
    "profile with a repeated time": (_profile_rows(lambda rows: [rows[0], rows[0], *rows[2:]]),
                                     "profile.csv", "t_s"),
    "load missing": (_remove("load.toml"), "load.toml", ""),
    "load bad": (_edit("load.toml", "layers = 2", "layers = 0"), "load.toml", "stack.layers"),
}


@pytest.fixture
def copy_of(recording_dir, tmp_path) -> Callable[[], Path]:
    def make() -> Path:
        folder = tmp_path / "rec"
        shutil.copytree(recording_dir, folder)
        return folder
    return make


@pytest.mark.parametrize("case", CASES)
def test_bad_recording_is_one_input_error(case, copy_of, assert_input_error):
    change, file, field = CASES[case]
    folder = copy_of()
    change(folder)
    with pytest.raises(InputError) as err:
        Recording.read(folder)
    assert_input_error(err.value, str(folder / file), field)


@pytest.mark.parametrize("damage, words", [
    (_empty_video, "no decodable frame (the container states none)"),
    (_damage_first_frame, "the first of the 32 it states does not decode"),
], ids=["no frame", "first frame damaged"])
def test_a_video_must_decode_from_its_first_frame(damage, words, copy_of, capfd,
                                                  assert_input_error):
    """A damaged first frame was reported as no frame at all; the error says which it is, on
    one line, without the decoder's own complaint."""
    folder = copy_of()
    damage(folder)
    with pytest.raises(InputError) as err:
        Recording.read(folder)
    assert_input_error(err.value, str(folder / "video.avi"), "")
    assert words in str(err.value)
    assert capfd.readouterr().err == ""


def test_missing_folder(tmp_path, assert_input_error):
    with pytest.raises(InputError) as err:
        Recording.read(tmp_path / "nowhere")
    assert_input_error(err.value, str(tmp_path / "nowhere"), "")


def test_template_may_sit_under_recording(copy_of):
    folder = copy_of()
    _edit("setup.toml", 'template = "template.png"\n', "")(folder)
    _edit("setup.toml", "[recording]\n", '[recording]\ntemplate = "template.png"\n')(folder)
    assert read_toml(folder / "setup.toml")["recording"]["template"] == "template.png"
    assert Recording.read(folder).template == folder / "template.png"


def test_wrap_file_is_read(wrapped_dir):
    rec = Recording.read(wrapped_dir)
    assert rec.wrap is not None and rec.wrap.material_key == "kraft"


@pytest.mark.parametrize("change, field", [
    ('"x_m": [', "objects.pallet.x_m"),
    ('"angle_rad": [', "objects.pallet.angle_rad"),
])
def test_bad_truth_is_one_input_error(change, field, copy_of, assert_input_error):
    folder = copy_of()
    path = folder / "truth.json"
    text = path.read_text()
    start = text.index('"pallet"')
    at = text.index(change, start) + len(change)
    # one value too many (length mismatch) for x_m, a string for angle_rad
    extra = "0.0, " if "x_m" in change else '"a", '
    path.write_text(text[:at] + extra + text[at:])
    with pytest.raises(InputError) as err:
        Truth.read(folder)
    assert_input_error(err.value, str(path), field)


@pytest.mark.parametrize("change, field", [
    (lambda data: data.update(params=[0.4, 0.3]), "params"),
    (lambda data: data.pop("objects"), "objects"),
    (lambda data: data.update(objects={}), "objects"),
    (lambda data: data["objects"].update(pallet=[0.0, 0.1]), "objects.pallet"),
    (lambda data: data["objects"]["pallet"]["z_m"].__setitem__(0, math.nan),
     "objects.pallet.z_m"),
], ids=["params a list", "no objects", "objects empty", "a track a list", "NaN in a track"])
def test_truth_of_the_wrong_shape_is_one_input_error(change, field, copy_of, assert_input_error):
    folder = copy_of()
    path = folder / "truth.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))   # NaN written as JSON's NaN token, which Python reads
    with pytest.raises(InputError) as err:
        Truth.read(folder)
    assert_input_error(err.value, str(path), field)


def _empty_pallet(objects: dict) -> None:
    objects["pallet"] = {key: [] for key in objects["pallet"]}


def _pallet_backwards(objects: dict) -> None:
    objects["pallet"]["t_s"].reverse()


def _pallet_time_repeated(objects: dict) -> None:
    objects["pallet"]["t_s"][1] = objects["pallet"]["t_s"][0]


@pytest.mark.parametrize("change, message", [(_empty_pallet, "at least one sample"),
                                             (_pallet_backwards, "increase strictly"),
                                             (_pallet_time_repeated, "increase strictly")],
                         ids=["empty", "backwards", "a time repeated"])
def test_truth_tracks_need_samples_in_time_order(change, message, copy_of, assert_input_error):
    """The error against truth interpolates in each track: an empty one was an IndexError,
    times out of order gave a wrong error silently."""
    folder = copy_of()
    path = folder / "truth.json"
    data = json.loads(path.read_text())
    change(data["objects"])
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match=message) as err:
        Truth.read(folder)
    assert_input_error(err.value, str(path), "objects.pallet.t_s")


def test_profile_in_milliseconds_is_refused(copy_of, assert_input_error):
    """t_s written in ms makes a 3000 s test: the sled would creep and a replay run for hours."""
    folder = copy_of()
    path = folder / "profile.csv"
    lines = path.read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    path.write_text("\n".join([lines[0]] + [",".join([repr(1000 * float(r[0])), *r[1:]])
                                            for r in rows]) + "\n")
    with pytest.raises(InputError) as err:
        Recording.read(folder)
    assert_input_error(err.value, str(path), "t_s")
    assert "milliseconds" in str(err.value)


def test_profile_with_a_byte_order_mark_reads(copy_of):
    """Excel's "CSV UTF-8" starts the file with U+FEFF, which hid the first column's name."""
    folder = copy_of()
    path = folder / "profile.csv"
    plain = Recording.read(folder).profile
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    np.testing.assert_array_equal(Recording.read(folder).profile.t_s, plain.t_s)


def test_missing_template_is_one_line_without_opencv_noise(copy_of, capfd, assert_input_error):
    folder = copy_of()
    (folder / "template.png").unlink()
    with pytest.raises(InputError) as err:
        Recording.read(folder)
    assert_input_error(err.value, str(folder / "setup.toml"), "template")
    assert capfd.readouterr().err == ""


def test_marker_size_is_optional(copy_of):
    """CONTRACTS.md: `markers.size_m` may be left out (a lab may not know the printed size)."""
    folder = copy_of()
    _edit("setup.toml", "size_m = 0.075\n", "")(folder)
    rec = Recording.read(folder)
    assert rec.markers is not None and rec.markers.size_m is None
    assert len(rec.markers.placements) == 2


def _profile(path: Path, t_s: list[float]) -> Path:
    path.write_text("t_s,accel_mps2\n" + "".join(f"{t!r},0.0\n" for t in t_s))
    return path


def test_two_samples_are_the_least_a_profile_needs(tmp_path):
    profile = SledProfile.read(_profile(tmp_path / "profile.csv", [0.0, 3.2]))
    np.testing.assert_array_equal(profile.t_s, [0.0, 3.2])


@pytest.mark.parametrize("t_s, refused", [([-1.0, 1.0, 119.0], False),
                                          ([-1.0, 1.0, 120.0], True)],
                         ids=["120 s", "121 s"])
def test_a_profile_spans_at_most_120_s_from_its_first_sample_to_its_last(
        t_s, refused, tmp_path, assert_input_error):
    """A pre-trigger record may start before the first frame; what counts is the whole span,
    first sample to last (here 120 s is read, 121 s is milliseconds or a day's log)."""
    path = _profile(tmp_path / "profile.csv", t_s)
    if not refused:
        assert SledProfile.read(path).t_s[-1] == t_s[-1]
        return
    with pytest.raises(InputError, match=r"spans 121 s, longer than the 120 s") as err:
        SledProfile.read(path)
    assert_input_error(err.value, str(path), "t_s")


def _ending_at(end_s: float) -> Callable[[Path], None]:
    """profile.csv cut at `end_s`, its last sample there."""
    def cut(rows: list[str]) -> list[str]:
        kept = [r for r in rows if float(r.split(",")[0]) < end_s]
        return [*kept, ",".join([repr(end_s), *kept[-1].split(",")[1:]])]
    return _profile_rows(cut)


def test_a_profile_must_reach_the_last_frame(copy_of, assert_input_error):
    """The fixture's video has 32 frames at 10 fps: its last is at 3.1 s. A profile that ends
    there covers it; one that ends half a frame earlier does not, and says both times."""
    folder = copy_of()
    _ending_at(3.1)(folder)
    assert Recording.read(folder).profile.t_s[-1] == 3.1
    _ending_at(3.05)(folder)
    with pytest.raises(InputError) as err:
        Recording.read(folder)
    assert_input_error(err.value, str(folder / "profile.csv"), "t_s")
    assert "ends at 3.05 s, before the video's last frame at 3.1 s" in str(err.value)


def test_a_late_profile_says_when_it_starts(copy_of):
    folder = copy_of()
    _profile_rows(_later)(folder)
    with pytest.raises(InputError, match=r"starts at 1 s, after the first frame"):
        Recording.read(folder)


@pytest.mark.parametrize("fps, refused", [(10.005, False), (10.012, True)],
                         ids=["0.05 % off", "0.12 % off"])
def test_setup_fps_matches_the_container_within_a_tenth_of_a_percent(
        fps, refused, copy_of, assert_input_error):
    """Containers store the rate as a fraction: 0.1 % covers its rounding, and no more."""
    folder = copy_of()
    _edit("setup.toml", "fps = 10.0", f"fps = {fps}")(folder)
    if not refused:
        assert Recording.read(folder).fps == fps
        return
    with pytest.raises(InputError, match="does not match the video's 10 fps") as err:
        Recording.read(folder)
    assert_input_error(err.value, str(folder / "setup.toml"), "recording.fps")


@pytest.mark.parametrize("share, refused", [(0.015, True), (0.025, False), (2.9, False),
                                            (3.1, True)])
def test_the_pallet_spans_2_to_300_percent_of_the_frame(share, refused, copy_of,
                                                        assert_input_error):
    """The fixture's 0.6 m pallet on an 800 px wide video: px_per_m is the share x 800 / 0.6."""
    folder = copy_of()
    _px_per_m_times(share * 800 / 0.6 / Recording.read(folder).px_per_m)(folder)
    if not refused:
        assert Recording.read(folder).px_per_m == pytest.approx(share * 800 / 0.6)
        return
    with pytest.raises(InputError) as err:
        Recording.read(folder)
    assert_input_error(err.value, str(folder / "setup.toml"), "camera.px_per_m")
    assert f"spans {share * 800:.3g} px of the video's 800 px" in str(err.value)


def test_inputs_name_the_template_only_when_there_is_one(copy_of):
    folder = copy_of()
    names = ("setup.toml", "profile.csv", "load.toml", "wrap.toml", "truth.json")
    assert Recording.read(folder).inputs() == (
        folder / "video.avi", *(folder / n for n in names), folder / "template.png")
    _edit("setup.toml", 'template = "template.png"\n', "")(folder)
    assert Recording.read(folder).inputs() == (folder / "video.avi",
                                               *(folder / n for n in names))


def _tracked(t_s: list[float], name: str = "L1C1R1") -> Trajectories:
    t = np.array(t_s)
    return Trajectories({name: ObjectPath(t, np.zeros_like(t), np.zeros_like(t),
                                          np.zeros_like(t))})


def test_trajectories_may_end_at_the_profile_rounded_up_to_the_microsecond(copy_of):
    """trajectories.csv writes times to microseconds: a path to the profile's end may round
    past it."""
    rec = Recording.read(copy_of())
    end_s = float(rec.profile.t_s[-1])
    assert end_s != round(end_s, 6)
    rec.check_trajectories(_tracked([0.0, math.ceil(end_s * 1e6) / 1e6]), "t.csv")


@pytest.mark.parametrize("t_s, words", [
    ([-0.5, 3.0], "runs from -0.5 to 3 s, outside profile.csv's 0 to"),
    ([0.0, 3.2], "runs from 0 to 3.2 s, outside profile.csv's 0 to"),
], ids=["starting before", "ending after"])
def test_trajectories_outside_the_profile_are_refused(t_s, words, copy_of, assert_input_error):
    rec = Recording.read(copy_of())
    with pytest.raises(InputError, match=words) as err:
        rec.check_trajectories(_tracked(t_s), "t.csv")
    assert_input_error(err.value, "t.csv", "object L1C1R1: t_s")


def test_an_object_the_load_lacks_is_named_with_the_load_s_bundles(copy_of, assert_input_error):
    rec = Recording.read(copy_of())
    with pytest.raises(InputError, match=r"bundles L1C1R1 \.\.\. L2C2R2\)") as err:
        rec.check_trajectories(_tracked([0.0, 1.0], "L3C1R1"), "t.csv")
    assert_input_error(err.value, "t.csv", "object L3C1R1")

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
    "profile out of time order": (_profile_rows(lambda rows: [rows[1], rows[0], *rows[2:]]),
                                  "profile.csv", "t_s"),
    "profile with a word for a number": (_profile_rows(lambda rows: [
        rows[0], "0.05,fast,0,0", *rows[2:]]), "profile.csv", "line 3"),
    "profile starting after the first frame": (_profile_rows(_later), "profile.csv", "t_s"),
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


@pytest.mark.parametrize("change, message", [(_empty_pallet, "at least one sample"),
                                             (_pallet_backwards, "increase strictly")],
                         ids=["empty", "backwards"])
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

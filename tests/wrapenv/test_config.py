"""Outputs checked before any work (`check_output`, `check_output_folder`): a run must not end
in a failed write, a traceback, or a destroyed input."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from wrapenv.config import (
    InputError,
    Table,
    check_checkpoint,
    check_distinct,
    check_output,
    check_output_folder,
    printable,
    read_csv,
    read_json,
    read_toml,
    result_json,
    write_together,
)

ROOT = os.geteuid() == 0


def _refused(path: Path | str, *needles: str, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        check_output(Path(path), "--out", **kwargs)
    message = str(info.value)
    assert "\n" not in message and "--out" in message
    for needle in needles:
        assert needle in message, message
    return message


def test_a_file_in_an_existing_folder_is_accepted(tmp_path: Path) -> None:
    check_output(tmp_path / "new.csv", "--out")
    (tmp_path / "old.csv").write_text("replaced at the end")
    check_output(tmp_path / "old.csv", "--out")
    check_output(None, "--out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.csv"]  # the probe cleaned up


def test_a_missing_folder_is_refused(tmp_path: Path) -> None:
    _refused(tmp_path / "no" / "t.csv", "does not exist")


def test_a_folder_is_refused(tmp_path: Path) -> None:
    _refused(tmp_path, "is a folder")


def test_a_device_is_refused() -> None:
    """`os.replace` would put a regular file where /dev/null was."""
    _refused("/dev/null", "not a regular file")


def test_a_file_system_that_takes_no_files_is_refused() -> None:
    _refused("/proc/trajectories.csv", "cannot write into /proc")


@pytest.mark.skipif(ROOT, reason="root writes into read-only folders")
def test_a_read_only_folder_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "ro"
    folder.mkdir(mode=0o555)
    _refused(folder / "t.csv", "cannot write into")


def test_an_input_is_refused_by_any_name(tmp_path: Path) -> None:
    source = tmp_path / "video.avi"
    source.write_bytes(b"precious")
    (tmp_path / "link.avi").symlink_to(source)
    for name in ("video.avi", "link.avi", "./video.avi"):
        _refused(tmp_path / name, "is an input", inputs=[source])
    check_output(tmp_path / "other.avi", "--out", inputs=[source, tmp_path / "absent.csv"])
    assert source.read_bytes() == b"precious"


def test_an_output_folder_must_be_new_or_empty_and_creatable(tmp_path: Path) -> None:
    check_output_folder(tmp_path / "a" / "b" / "rec", "--out")
    (tmp_path / "empty").mkdir()
    check_output_folder(tmp_path / "empty", "--out")
    assert not (tmp_path / "a").exists()  # checked, not created
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    (tmp_path / "file").write_text("")
    for path, needle in ((tmp_path / "full", "not an empty folder"),
                         (tmp_path / "file", "not an empty folder"),
                         (tmp_path / "file" / "rec", "not a folder"),
                         (Path("/proc/rec"), "cannot write into /proc")):
        with pytest.raises(InputError, match=needle):
            check_output_folder(path, "--out")


def test_a_checkpoint_may_replace_only_a_checkpoint_of_its_kind(tmp_path: Path) -> None:
    """A run removes its checkpoint once it has answered: a user's file at that path would be
    overwritten, then deleted."""
    check_checkpoint(tmp_path / "new.json", "--checkpoint", "wrapbench-search/")
    ours = tmp_path / "search.json"
    ours.write_text('{"format": "wrapbench-search/1", "generations": []}\n')
    check_checkpoint(ours, "--checkpoint", "wrapbench-search/")   # an older version of ours
    for name, text in (("notes.txt", "my lab notes\n"), ("load.toml", "[pallet]\n"),
                       ("cal.jsonl", '{"format": "wrapbench-calibration-replays/1"}\n'),
                       ("list.json", "[1, 2]\n"), ("empty.json", "")):
        mine = tmp_path / name
        mine.write_text(text)
        with pytest.raises(InputError, match="not a wrapbench checkpoint") as info:
            check_checkpoint(mine, "--checkpoint", "wrapbench-search/")
        assert info.value.field == "--checkpoint" and mine.read_text() == text


def test_printable_escapes_control_characters_and_truncates() -> None:
    assert printable("L\x1b[31mred\x07 é 中") == "L\\x1b[31mred\\x07 é 中"
    assert printable("a\nb\tc\u200bd") == "a\\nb\\tc\\u200bd"
    long = printable("x" * 100_000, limit=80)
    assert len(long) <= 80 and long.startswith("x" * 20) and "99920 more characters" in long
    # the middle is dropped: both ends are kept, and a text as long as the limit is whole
    ends = printable("a" * 50 + "b" * 50, limit=40)
    assert len(ends) == 40 and ends.startswith("a") and ends.endswith("b" * 2)
    assert printable("c" * 40, limit=40) == "c" * 40


def test_two_outputs_naming_one_file_by_any_path_are_refused(tmp_path: Path) -> None:
    """The later write would replace the earlier one: the same path, a path through `..`, or
    a hard link to the same file; outputs not asked (None) are no file."""
    (tmp_path / "sub").mkdir()
    check_distinct({"--json": tmp_path / "a.json", "--wrap-out": tmp_path / "b.toml",
                    "--report": None})
    with pytest.raises(InputError, match="is also --json") as info:
        check_distinct({"--json": tmp_path / "a.json",
                        "--wrap-out": tmp_path / "sub" / ".." / "a.json"})
    assert info.value.field == "--wrap-out"
    (tmp_path / "a.json").write_text("{}")
    os.link(tmp_path / "a.json", tmp_path / "linked.json")
    with pytest.raises(InputError, match="is also --json"):
        check_distinct({"--json": tmp_path / "a.json", "--wrap-out": tmp_path / "linked.json"})


def test_a_toml_file_with_a_byte_order_mark_is_read_as_without_one(tmp_path):
    """Windows editors write one; it is not part of the first key. Other bytes than UTF-8
    stay malformed."""
    marked = tmp_path / "load.toml"
    marked.write_bytes(b"\xef\xbb\xbfname = 'x'\n[pallet]\npreset = 'EUR'\n")
    assert read_toml(marked) == {"name": "x", "pallet": {"preset": "EUR"}}
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b"name = '\xe9'\n")
    with pytest.raises(InputError, match="malformed TOML"):
        read_toml(latin)


def test_a_json_key_given_twice_is_an_error_naming_it(tmp_path, assert_input_error):
    path = tmp_path / "CAL.json"
    path.write_text('{"wrap": {"stiffness_scale": 1.0, "stiffness_scale": 2.0}}')
    with pytest.raises(InputError) as info:
        read_json(path)
    assert_input_error(info.value, str(path), "stiffness_scale")


def test_files_written_together_are_all_written_or_none(tmp_path):
    first, second = tmp_path / "cal.json", tmp_path / "gone" / "cal-loss.png"
    with pytest.raises(OSError):
        write_together({first: b"{}", second: b"png"})
    assert list(tmp_path.iterdir()) == []           # nothing, not even a staged file
    write_together({first: b"{}", tmp_path / "cal-loss.png": b"png"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal-loss.png", "cal.json"]
    assert oct(first.stat().st_mode & 0o777) == oct(0o666 & ~_umask())


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def test_a_result_with_a_nan_is_a_bug_not_a_file():
    """No JSON reader need accept NaN: a result that holds one is refused before writing."""
    assert result_json({"x": 1.0}).endswith(b"\n")
    with pytest.raises(ValueError):
        result_json({"x": float("nan")})


def test_csv_rows_carry_the_line_they_end_on(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("\ufefft_s,accel_mps2\n\n\n0,0\n0.1,abc\n")
    header, rows = read_csv(path)
    assert header == ["t_s", "accel_mps2"]
    assert rows == [(4, ["0", "0"]), (5, ["0.1", "abc"])]


@pytest.mark.parametrize("text, needles", [
    ("", ["empty file"]),
    ("a,b\n" + "x" * 200_000 + ",1\n", ["line 2", "malformed CSV", "field larger"]),
    (b"t_s\n\xff\xfe".decode("latin-1"), ["not UTF-8 text"]),
    # a spreadsheet's export in a European locale: ';' between columns, ',' for decimals
    ("t_s;accel_mps2\n0,0;0,0\n0,1;2,5\n", ["line 1", "separated by ';'", "comma-separated"]),
    ("t_s\taccel_mps2\n0.0\t0.0\n", ["line 1", "separated by tabs", "comma-separated"]),
])
def test_a_csv_that_cannot_be_read_names_the_file_and_line(text, needles, tmp_path):
    path = tmp_path / "p.csv"
    path.write_bytes(text.encode("latin-1") if "\xff" in text else text.encode())
    with pytest.raises(InputError) as err:
        read_csv(path)
    assert str(err.value).startswith(str(path))
    assert all(n in str(err.value) for n in needles), err.value


def test_a_missing_csv_is_named_like_any_missing_input(tmp_path):
    with pytest.raises(InputError, match=r"cannot read file \(No such file or directory\)$"):
        read_csv(tmp_path / "nope.csv")


def test_a_whole_number_written_with_a_decimal_point_is_taken_as_one():
    """TOML reads 3.0 as a float; a count written so is still 3 (3.5 is not a count)."""
    table = Table({"wraps": 3.0, "layers": 3.5, "flag": True}, "f.toml")
    assert table.integer("wraps") == 3 and isinstance(table.integer("wraps"), int)
    with pytest.raises(InputError, match=r"layers: must be a whole number \(got 3\.5\)"):
        table.integer("layers")
    with pytest.raises(InputError, match="flag: must be a whole number"):
        table.integer("flag")



def test_a_whole_number_s_bounds_are_inclusive():
    table = Table({"wraps": 20, "more": 21, "none": -1}, "f.toml")
    assert table.integer("wraps", minimum=0, maximum=20) == 20
    with pytest.raises(InputError, match=r"more: must be <= 20 \(got 21\)"):
        table.integer("more", maximum=20)
    with pytest.raises(InputError, match=r"none: must be >= 0 \(got -1\)"):
        table.integer("none", minimum=0)

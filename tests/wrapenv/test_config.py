"""Outputs checked before any work (`check_output`, `check_output_folder`): a run must not end
in a failed write, a traceback, or a destroyed input."""

from __future__ import annotations

import math
import os
import pickle
from pathlib import Path

import numpy as np
import pytest

from wrapenv.config import (
    InputError,
    Table,
    check_checkpoint,
    check_distinct,
    check_output,
    check_output_folder,
    fraction_hint,
    is_finite_number,
    is_real_number,
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


def test_a_json_file_is_read_as_toml_is_utf8_with_or_without_a_byte_order_mark(tmp_path):
    """A CAL.json saved by a Windows editor starts with a BOM ("Unexpected UTF-8 BOM" before);
    Latin-1 is still malformed."""
    marked = tmp_path / "bom.json"
    marked.write_bytes(b'\xef\xbb\xbf{"wrap": {"give_scale": 1.5}}')
    assert read_json(marked) == {"wrap": {"give_scale": 1.5}}
    latin = tmp_path / "latin.json"
    latin.write_bytes(b'{"name": "\xe9"}')
    with pytest.raises(InputError, match=str(latin)):
        read_json(latin)


def test_an_input_error_raised_in_a_worker_process_reaches_the_command_as_itself():
    """Pickled and unpickled as a process pool returns it: the same file, field and line (it
    failed to unpickle, and the command saw a TypeError instead)."""
    error = pickle.loads(pickle.dumps(InputError("load.toml", "stack.layers", "must be >= 1")))
    assert isinstance(error, InputError)
    assert (error.source, error.field, str(error)) == (
        "load.toml", "stack.layers", "load.toml: stack.layers: must be >= 1")


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


# --- a table validated as it is taken ---------------------------------------------------------


def _refuses(take, message: str) -> None:
    with pytest.raises(InputError, match=message):
        take()


def test_a_number_is_finite_and_within_its_inclusive_bounds():
    t = Table({"mass_kg": 20, "on": True, "name": "x", "nan": float("nan"), "zero": 0.0},
              "load.toml", "pallet")
    assert t.number("mass_kg", minimum=20, maximum=20) == 20.0
    assert isinstance(t.number("mass_kg"), float)
    assert t.number("absent_m", 0.5) == 0.5                          # a default when absent
    _refuses(lambda: t.number("on"), r"pallet\.on: must be a number \(got True\)")
    _refuses(lambda: t.number("name"), r"pallet\.name: must be a number \(got 'x'\)")
    _refuses(lambda: t.number("nan"), r"pallet\.nan: must be finite \(got nan\)")
    _refuses(lambda: t.number("zero", positive=True), r"must be > 0 \(got 0\.0\)")
    _refuses(lambda: t.number("mass_kg", minimum=20.5), r"must be >= 20\.5 \(got 20\.0\)")
    _refuses(lambda: t.number("mass_kg", maximum=19.5), r"must be <= 19\.5 \(got 20\.0\)$")
    _refuses(lambda: t.number("height_m"), r"load\.toml: pallet\.height_m: missing")


def test_a_value_too_large_names_the_unit_it_was_likely_written_in():
    """144 for a height of at most 3 m reads as millimetres (0.144 m fits); 25 000 for at most
    2000 kg as grams. A figure just past its bound (3.2 m, 2500 kg) is no slip of a thousand
    (it read as one until 2026-12-01), and 5000 km is no height in millimetres either."""
    t = Table({"height_m": 144.0, "far_m": 5000000.0, "mass_kg": 25000.0, "turns": 500.0,
               "tall_m": 3.2, "safe_kg": 2500.0}, "load.toml")
    _refuses(lambda: t.number("height_m", maximum=3.0),
             r"must be <= 3\.0 \(got 144\.0\): millimetres\? height_m is in metres$")
    _refuses(lambda: t.number("tall_m", maximum=3.0), r"must be <= 3\.0 \(got 3\.2\)$")
    _refuses(lambda: t.number("safe_kg", maximum=2000.0), r"\(got 2500\.0\)$")
    _refuses(lambda: t.number("far_m", maximum=3.0), r"\(got 5000000\.0\)$")
    _refuses(lambda: t.number("mass_kg", maximum=2000.0),
             r"\(got 25000\.0\): grams\? mass_kg is in kilograms$")
    _refuses(lambda: t.number("turns", maximum=20.0), r"\(got 500\.0\)$")
    _refuses(lambda: t.number("height_m", maximum=3.0, hint="a pallet is 0.144 m"),
             r"\(got 144\.0\): a pallet is 0\.144 m$")
    assert fraction_hint(50.0, " of the web") == ": a fraction of the web (0.5 for 50 %)"
    assert fraction_hint(1.0) == ": a fraction (0.01 for 1 %)" and fraction_hint(0.5) == ""


def test_strings_flags_choices_and_arrays_are_taken_by_their_type():
    t = Table({"name": "EUR", "stopper": True, "pattern": "columnar", "positions": [[0, 0]],
               "count": 3}, "load.toml", "stack")
    assert t.string("name") == "EUR" and t.boolean("stopper") is True
    assert t.choice("pattern", ("columnar", "interlocked")) == "columnar"
    assert t.array("positions") == [[0, 0]]
    assert t.string("absent", "default") == "default" and t.boolean("off", False) is False
    _refuses(lambda: t.string("count"), r"stack\.count: must be a string \(got 3\)")
    _refuses(lambda: t.boolean("name"), r"stack\.name: must be true or false \(got 'EUR'\)")
    _refuses(lambda: t.choice("name", ("a", "b")), r"must be one of 'a', 'b' \(got 'EUR'\)")
    _refuses(lambda: t.array("name"), r"stack\.name: must be an array \(got 'EUR'\)")
    _refuses(lambda: t.array("absent_list"), r"stack\.absent_list: missing")


def test_keys_left_untaken_are_unknown_the_first_in_order_named():
    t = Table({"mass_kg": 20.0, "mass_kgs": 21.0, "colour": "red", "note": "x"}, "load.toml",
              "bundle")
    assert t.has("mass_kg") and not t.has("length_m")
    t.number("mass_kg")
    t.ignore("note")
    _refuses(t.done, r"load\.toml: bundle\.colour: unknown key")
    t.string("colour")
    _refuses(t.done, r"bundle\.mass_kgs: unknown key")
    t.number("mass_kgs")
    t.done()


def test_a_table_is_a_table_and_a_nested_one_names_its_path():
    _refuses(lambda: Table([1, 2], "load.toml"), r"load\.toml: \(top level\): expected a table")
    top = Table({"pallet": {"mass_kg": "heavy"}, "stack": 3}, "load.toml")
    _refuses(lambda: top.table("pallet").number("mass_kg"), r"pallet\.mass_kg: must be a number")
    _refuses(lambda: top.table("stack"), r"load\.toml: stack: expected a table")
    assert top.table("fixture").has("pallet_stopper") is False      # absent: an empty table
    _refuses(lambda: top.table("bundle", required=True), r"bundle: missing")


def test_a_number_is_real_and_not_a_flag():
    assert is_real_number(3) and is_real_number(np.float32(0.5)) and is_real_number(math.inf)
    assert not is_real_number(True) and not is_real_number("3")
    assert is_finite_number(0.5) and not is_finite_number(math.nan)
    assert not is_finite_number(math.inf) and not is_finite_number(False)

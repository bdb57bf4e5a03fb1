"""Reading and validating the project's input files in one place.

Every user-facing file (LOAD.toml, WRAP.toml, CAL.json, profile.csv) is read through the
`Table` reader below, so a bad value always produces the same one-line message naming the
file and the field: ``load.toml: bundle.mass_kg: must be > 0 (got -1.0)``.
"""

from __future__ import annotations

import csv
import json
import math
import numbers
import os
import tempfile
import tomllib
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TypeGuard

from wrapenv import __version__

#: The largest friction coefficient any file may give (a load's pairs, a calibration's, a
#: web's layer on layer): rubber on dry steel reaches about 1, so 2 leaves room and still
#: refuses a percentage or an angle.
MAX_FRICTION_COEFFICIENT = 2.0


class InputError(ValueError):
    """Bad user input; ``str()`` is a one-line message naming the file and the field."""

    def __init__(self, source: str, field: str, message: str) -> None:
        self.source, self.field, self.message = source, field, message
        where = f"{source}: {field}" if field else source
        super().__init__(f"{where}: {message}")

    def __reduce__(self) -> tuple[type[InputError], tuple[str, str, str]]:
        """Pickled by its three parts: one raised in a worker process reaches the command as
        itself (by `args` alone it failed to unpickle, a TypeError in its place)."""
        return type(self), (self.source, self.field, self.message)


def read_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file, turning I/O and syntax errors into `InputError`. A byte-order mark
    (Windows editors write one) is not part of the first key."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_bytes().decode("utf-8-sig"))
    except OSError as exc:
        raise InputError(str(path), "", f"cannot read file ({exc.strerror or exc})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(str(path), "", f"malformed TOML ({exc})") from None


def read_csv(path: str | Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """A CSV file's header (its cells stripped) and its other rows, each with the number of the
    line it ends on (blank rows skipped), turning I/O and syntax errors into `InputError`. A
    byte-order mark (Excel writes one) is not part of the first column's name."""
    path = Path(path)
    rows: list[tuple[int, list[str]]] = []
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            try:
                rows += ((reader.line_num, row) for row in reader if row)
            except csv.Error as exc:
                raise InputError(str(path), f"line {reader.line_num}",
                                 f"malformed CSV ({exc})") from None
    except OSError as exc:
        raise InputError(str(path), "", f"cannot read file ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise InputError(str(path), "", "cannot read file (not UTF-8 text)") from None
    if not rows:
        raise InputError(str(path), "", "empty file")
    header = [h.strip() for h in rows[0][1]]
    for sep, name in ((";", "';'"), ("\t", "tabs")):
        if len(header) == 1 and sep in header[0]:
            raise InputError(str(path), f"line {rows[0][0]}",
                             f"columns separated by {name}: the bench reads comma-separated "
                             "values with '.' for decimals (a spreadsheet saving CSV in a "
                             "European locale writes ';' and ',')")
    return header, rows[1:]


def read_json(path: str | Path) -> dict[str, Any]:
    """Parse a JSON object file, turning I/O and syntax errors into `InputError`. A key given
    twice in one object is an error (JSON allows it and keeps the last: a silent typo)."""
    path = Path(path)
    try:
        # as TOML and CSV are read: UTF-8, a byte-order mark (Windows' editors) skipped
        data = json.loads(path.read_bytes().decode("utf-8-sig"), object_pairs_hook=_unique_keys)
    except OSError as exc:
        raise InputError(str(path), "", f"cannot read file ({exc.strerror or exc})") from None
    except _DuplicateKey as exc:
        raise InputError(str(path), str(exc), "given twice") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(str(path), "", f"malformed JSON ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(str(path), "", "expected a JSON object at the top level")
    return data


class _DuplicateKey(ValueError):
    pass


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


class Table:
    """A view on one table of a parsed file that validates values as they are taken.

    Call `done()` after taking every known key: leftover keys are reported as unknown, which
    catches typos such as ``mass_kgs`` instead of silently using a default.
    """

    def __init__(self, data: Any, source: str, prefix: str = "") -> None:
        if not isinstance(data, dict):
            raise InputError(source, prefix or "(top level)", "expected a table")
        self.data, self.source, self.prefix = data, source, prefix
        self._taken: set[str] = set()

    def field(self, key: str) -> str:
        return f"{self.prefix}.{key}" if self.prefix else key

    def error(self, key: str, message: str) -> InputError:
        return InputError(self.source, self.field(key), message)

    def has(self, key: str) -> bool:
        return key in self.data

    def _get(self, key: str, default: Any) -> Any:
        """Take a key (marking it known); `default` is `_REQUIRED` for mandatory keys."""
        self._taken.add(key)
        if key in self.data:
            return self.data[key]
        if default is _REQUIRED:
            raise self.error(key, "missing")
        return default

    def number(
        self,
        key: str,
        default: Any = None,
        *,
        positive: bool = False,
        minimum: float | None = None,
        maximum: float | None = None,
        hint: str = "",
    ) -> float:
        """A finite number within the bounds; `hint` says what a value above `maximum` most
        likely is (by default, for a key in metres or kilograms, a value in millimetres or
        grams if it is well beyond the bound and fits it as one: `_unit_slip`)."""
        value = self._get(key, _REQUIRED if default is None else default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(key, f"must be a number (got {value!r})")
        value = float(value)
        if not math.isfinite(value):
            raise self.error(key, f"must be finite (got {value})")
        if positive and value <= 0:
            raise self.error(key, f"must be > 0 (got {value})")
        if minimum is not None and value < minimum:
            raise self.error(key, f"must be >= {minimum} (got {value})")
        if maximum is not None and value > maximum:
            raise self.error(key, f"must be <= {maximum} (got {value})"
                             + (f": {hint}" if hint else _unit_slip(key, value, maximum)))
        return value

    def integer(self, key: str, default: Any = None, *, minimum: int | None = None,
                maximum: int | None = None) -> int:
        """A whole number; one written with a decimal point (3.0, a float to TOML) is taken."""
        value = self._get(key, _REQUIRED if default is None else default)
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not is_whole_number(value):
            raise self.error(key, f"must be a whole number (got {value!r})")
        if minimum is not None and value < minimum:
            raise self.error(key, f"must be >= {minimum} (got {value})")
        if maximum is not None and value > maximum:
            raise self.error(key, f"must be <= {maximum} (got {value})")
        return value

    def choice(self, key: str, choices: Iterable[str], default: Any = None) -> str:
        choices = tuple(choices)
        value = self._get(key, _REQUIRED if default is None else default)
        if value not in choices:
            raise self.error(key, f"must be one of {', '.join(map(repr, choices))} (got {value!r})")
        return value

    def string(self, key: str, default: Any = None) -> str:
        value = self._get(key, _REQUIRED if default is None else default)
        if not isinstance(value, str):
            raise self.error(key, f"must be a string (got {value!r})")
        return value

    def boolean(self, key: str, default: Any = None) -> bool:
        value = self._get(key, _REQUIRED if default is None else default)
        if not isinstance(value, bool):
            raise self.error(key, f"must be true or false (got {value!r})")
        return value

    def table(self, key: str, *, required: bool = False) -> Table:
        value = self._get(key, _REQUIRED if required else {})
        return Table(value, self.source, self.field(key))

    def array(self, key: str) -> list[Any]:
        value = self._get(key, _REQUIRED)
        if not isinstance(value, list):
            raise self.error(key, f"must be an array (got {value!r})")
        return value

    def ignore(self, *keys: str) -> None:
        """Accept keys that carry information for people, not for the program."""
        self._taken.update(keys)

    def done(self) -> None:
        unknown = sorted(set(self.data) - self._taken)
        if unknown:
            raise self.error(unknown[0], "unknown key")


class _Required:
    def __repr__(self) -> str:
        return "<required>"


_REQUIRED: Any = _Required()


def check_output(path: Path | None, field: str, *, inputs: Iterable[str | Path] = ()) -> None:
    """An output file must be writable before any work starts, so a long run does not end in
    a failed write (`path` None: the output was not asked for): not a folder or a device, not
    one of the run's `inputs` (by any name), in an existing folder a file can be created in.
    `field`: the output's name in an error (what the user called it)."""
    if path is None:
        return
    path = Path(path)
    if path.is_dir():
        raise InputError(str(path), field, "is a folder; name a file to write")
    if path.exists() and not path.is_file():
        raise InputError(str(path), field, "not a regular file")
    for source in inputs:
        if path.exists() and Path(source).exists() and os.path.samefile(path, source):
            raise InputError(str(path), field, f"is an input ({source}): writing it would "
                             "destroy it")
    folder = path.resolve().parent
    if not folder.is_dir():
        raise InputError(str(path), field, "the folder to write into does not exist")
    _check_writable(folder, str(path), field)


def check_checkpoint(path: Path | None, field: str, format_prefix: str, *,
                     inputs: Iterable[str | Path] = ()) -> None:
    """A checkpoint is an output the run also deletes once it has answered: a file already
    there must be a checkpoint of this kind (its first line a JSON object whose `format` starts
    with `format_prefix`), not a user's file that would be overwritten, then removed."""
    check_output(path, field, inputs=inputs)
    if path is None or not Path(path).exists():
        return
    try:
        with Path(path).open(encoding="utf-8") as file:
            head = json.loads(file.readline())
    except (OSError, UnicodeDecodeError, ValueError):
        head = None
    kind = head.get("format") if isinstance(head, dict) else None
    if not (isinstance(kind, str) and kind.startswith(format_prefix)):
        raise InputError(str(path), field, "exists and is not a wrapbench checkpoint: it would "
                         "be overwritten, then removed; name a new file")


def check_distinct(outputs: dict[str, Path | None]) -> None:
    """No two outputs (the name an error gives it -> path; None: not asked) name one file: the
    later write would replace the earlier one."""
    given = [(field, Path(path)) for field, path in outputs.items() if path is not None]
    for i, (field, path) in enumerate(given):
        for earlier, other in given[:i]:
            if path.resolve() == other.resolve() or (
                    path.exists() and other.exists() and os.path.samefile(path, other)):
                raise InputError(str(path), field, f"is also {earlier}")


def check_output_folder(path: Path, field: str) -> None:
    """An output folder (created whole at the end) must be new or empty, and creatable: the
    nearest folder above it that exists must take new entries. Nothing is created."""
    path = Path(path)
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise InputError(str(path), field, "exists and is not an empty folder")
    above = path.absolute().parent
    while not above.exists():
        above = above.parent
    if not above.is_dir():
        raise InputError(str(path), field, f"{above} is not a folder")
    _check_writable(above, str(path), field)


def _check_writable(folder: Path, source: str, field: str) -> None:
    """Create and remove a file in `folder`: one test for permissions, read-only file systems
    and /proc alike (`os.access` says yes to root in read-only folders and in /proc)."""
    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".wrapbench-probe-")
    except OSError as exc:
        raise InputError(source, field, f"cannot write into {folder} "
                         f"({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)


def printable(text: str, limit: int = 200) -> str:
    """`text` safe to print on one line: characters that are not printable (escape codes, line
    breaks, zero-width) written as Python escapes, and at most `limit` characters, the middle
    dropped (a 100 kB load name would bury the output)."""
    safe = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    if len(safe) <= limit:
        return safe
    note = f" ... ({len(safe) - limit} more characters) ... "
    keep = max(limit - len(note), 2)
    return safe[:keep // 2] + note + safe[len(safe) - (keep - keep // 2):]


#: Longest path a message names whole (a lab's archive folders run long).
PATH_CHARS = 2000


def shown_path(path: object) -> str:
    """A path as a message names it: whole and safe to print."""
    return printable(str(path), PATH_CHARS)


def result_json(data: dict[str, Any]) -> bytes:
    """A command's JSON result, stamped with the version of the bench that produced it (a
    verdict on file can be traced to the model that gave it). Strict JSON: a NaN or infinity
    (no JSON reader need accept one) is a bug here, not a value to write."""
    stamped = {"wrapbench_version": __version__, **data}
    return (json.dumps(stamped, indent=2, allow_nan=False) + "\n").encode()


#: How many times its bound a value must be before it reads as written in a unit a thousand
#: times smaller: a bundle's 9.3 kg written in grams is 4.65 times the 2000 kg bound, a
#: height written in millimetres over 10 times the 3 m one; a figure just past its bound
#: (3.2 m, 2500 kg) is a figure too large.
UNIT_SLIP_BEYOND = 2.0
#: Units a value too large may have been written in, by the key's unit suffix: (factor, unit
#: written, unit meant).
_UNIT_SLIPS = {"_m": (1000.0, "millimetres", "metres"), "_kg": (1000.0, "grams", "kilograms")}


def _unit_slip(key: str, value: float, maximum: float) -> str:
    """": millimetres? <key> is in metres" when `value` is well beyond `maximum`
    (`UNIT_SLIP_BEYOND`) and fits it read in that unit."""
    for suffix, (factor, written, meant) in _UNIT_SLIPS.items():
        if key.endswith(suffix) and UNIT_SLIP_BEYOND * maximum <= value <= factor * maximum:
            return f": {written}? {key} is in {meant}"
    return ""


def fraction_hint(value: float, of: str = "") -> str:
    """": a fraction (0.5 for 50 %)" (`of`: " of the web", say) for a fraction's value that
    reads as a percentage (1 to 100), else ""."""
    return f": a fraction{of} ({value / 100:g} for {value:g} %)" if 1 <= value <= 100 else ""


def is_real_number(value: Any) -> bool:
    """A real number, Python's or NumPy's (an RL config's sampled np.float32), not a bool,
    though Python counts one as a number."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_whole_number(value: Any) -> TypeGuard[int]:
    """A Python int, not a bool (a flag passed where a count belongs)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_finite_number(value: Any) -> bool:
    """A finite real number (`is_real_number`), as a parsed file or a caller gives it."""
    return is_real_number(value) and math.isfinite(value)


def write_atomic(path: str | Path, data: bytes) -> None:
    """Write a file so readers see the old content or the whole new one, never a part."""
    write_together({Path(path): data})


def make_ordinary(path: str | Path) -> None:
    """Give a file made by `tempfile.mkstemp` (private to its owner) the permissions of any
    file the user creates (the umask's)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


def write_together(files: dict[Path, bytes]) -> None:
    """Write several files so that either all of them are written or none: each is staged in
    its folder first and put in place once every one is staged."""
    staged: dict[Path, str] = {}
    try:
        for path, data in files.items():
            fd, staged[path] = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                                suffix=".tmp")
            make_ordinary(staged[path])
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
        for path, tmp in staged.items():
            os.replace(tmp, path)
    except BaseException:
        for tmp in staged.values():
            Path(tmp).unlink(missing_ok=True)
        raise

"""The `wrapbench` command run in this process as a user runs it, and the one line a refused
command prints: what the commands' tests (tests/recommender, tests/calibration) share."""

from __future__ import annotations

from recommender.cli import main


def run(argv: list[str]) -> int:
    """The exit status: `main` returns it, or argparse exits with it (a usage error, --help)."""
    try:
        return main(argv)
    except SystemExit as exc:
        assert isinstance(exc.code, int), exc.code
        return exc.code


def one_line(err: str, *, warnings_aside: bool = False) -> str:
    """The one line on stderr, which must hold no traceback. With `warnings_aside`, lines saying
    ": warning: " are let be beside it: synth, track and calibrate warn about a recording (its
    markers' size, its profile, what the tracker lost) before an error they then end on."""
    lines = err.strip("\n").splitlines()
    if warnings_aside:
        lines = [line for line in lines if ": warning: " not in line]
    assert len(lines) == 1, f"expected one line on stderr, got: {err!r}"
    assert "Traceback" not in err
    return lines[0]

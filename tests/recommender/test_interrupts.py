"""Interrupting a running `wrapbench recommend`: Ctrl-C or SIGTERM ends it at once with one line,
its worker processes gone, nothing written but the checkpoint it can resume from; a second
Ctrl-C prints no traceback. Run as a user runs it: a process, signalled from outside."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

#: Four bundles on two layers: a search step is a few seconds, long enough to be interrupted.
SMALL = """name = "interrupt me"
[pallet]
preset = "EUR"
[bundle]
preset = "PET6x1.5L"
[stack]
layers = 2
pattern = "explicit"
positions = [[-0.15, -0.1], [0.15, -0.1], [-0.15, 0.1], [0.15, 0.1]]
[fixture]
pallet_stopper = true
"""
#: Seconds a killed search may take to wind down before the test calls it a hang.
HANG_S = 60


def _processes_naming(marker: str) -> list[int]:
    """Live processes whose command line names `marker` (the search and its workers)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            state = (entry / "stat").read_text().split()[2]
        except OSError:
            continue
        if marker in cmdline and state != "Z":
            found.append(int(entry.name))
    return found


def _as_from_a_terminal() -> None:
    """Ctrl-C's default action in the search, as a command typed at a terminal has it: a test
    run launched in the background (`cmd &` in a script) ignores SIGINT, the search would
    inherit that and run to its end (seen in CI run so: exit status 0 instead of 130)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _start(tmp_path: Path) -> tuple[subprocess.Popen, Path, Path]:
    load = tmp_path / "load.toml"
    load.write_text(SMALL)
    out = tmp_path / "rec.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "recommender.cli", "recommend", str(load), "--budget", "48",
         "--samples", "2", "--workers", "2", "--orientation", "long", "--json", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        cwd=Path(__file__).resolve().parents[2],
        # a hung search dumps every thread's stack on SIGABRT (see `_hung`)
        env={**os.environ, "PYTHONFAULTHANDLER": "1"}, preexec_fn=_as_from_a_terminal)
    checkpoint = tmp_path / "rec.checkpoint.json"
    deadline = time.monotonic() + 600
    while not checkpoint.exists():  # one generation done: the workers are busy with the next
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        assert time.monotonic() < deadline, "no generation finished"
        time.sleep(0.5)
    return proc, out, checkpoint


def _hung(proc: subprocess.Popen, marker: str) -> str:
    """Fail with where a search that did not exit is stuck: SIGABRT makes faulthandler print
    every thread's Python stack (an intermittent hang seen on 2026-11-24 left none). Its worker
    processes (naming `marker`) are killed first: one holding the stderr pipe open made reading
    it wait forever (2026-11-27)."""
    proc.send_signal(signal.SIGABRT)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
    for pid in _processes_naming(marker):
        os.kill(pid, signal.SIGKILL)
    stacks = proc.stderr.read() if proc.stderr else ""
    pytest.fail(f"the interrupted search hung; its threads:\n{stacks[-6000:]}")


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_interrupted_search_stops_its_workers_and_keeps_its_checkpoint(tmp_path, signum,
                                                                           code):
    proc, out, checkpoint = _start(tmp_path)
    proc.send_signal(signum)
    try:
        proc.wait(timeout=HANG_S)
    except subprocess.TimeoutExpired:
        _hung(proc, str(tmp_path))
    err = proc.stderr.read() if proc.stderr else ""
    assert proc.returncode == code
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert "--resume" in err and str(checkpoint) in err
    assert not out.exists()
    assert json.loads(checkpoint.read_text())["generations"]
    time.sleep(1)
    assert _processes_naming(str(tmp_path)) == [], "worker processes outlived the search"


def test_a_second_ctrl_c_prints_no_traceback(tmp_path):
    proc, _, _ = _start(tmp_path)
    proc.send_signal(signal.SIGINT)
    time.sleep(0.2)
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGINT)
    try:
        proc.wait(timeout=HANG_S)
    except subprocess.TimeoutExpired:
        _hung(proc, str(tmp_path))
    err = proc.stderr.read() if proc.stderr else ""
    assert "Traceback" not in err and proc.returncode == 130, err


def test_a_ctrl_c_inside_a_fork_is_raised_just_after_it():
    """Handled inside the fork hooks (logging's lock release as the worker pool starts), a
    KeyboardInterrupt is printed by Python as 'Exception ignored' with a traceback, and lost;
    the CLI's handler sends it again a moment later, to be raised in ordinary code."""
    from recommender import cli

    previous = signal.signal(signal.SIGINT, cli._interrupt)
    try:
        cli._Forking.starts()
        try:
            cli._interrupt(signal.SIGINT, None)   # inside the fork: not raised
        except KeyboardInterrupt:
            pytest.fail("raised inside the fork hooks, where Python drops it")
        cli._Forking.ended()
        with pytest.raises(KeyboardInterrupt):
            time.sleep(2)                         # ... but a moment later
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN   # and only once
    finally:
        cli._Forking.ended()
        signal.signal(signal.SIGINT, previous)

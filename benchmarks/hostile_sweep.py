"""The hostile-input sweep of issue 17, re-run: every case is a `wrapbench` command a careless or
hostile user could type, run as a separate process in a scratch folder. Each is checked for what
the product promises about bad input: exit status 2, one line on stderr naming the file or flag
(no traceback), and nothing written (no file added, none changed). Cases that are not bad
input (a BOM in profile.csv, a tiny video, an escaped name) are checked for their own promise.

    python -m benchmarks.hostile_sweep            # prints one row per case, exits 1 on a failure
    python -m benchmarks.hostile_sweep -k synth   # only the cases whose name contains 'synth'
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LOAD = (ROOT / "examples/pet_2layer_columnar.toml").read_text()
WRAP = (ROOT / "examples/program_kraft_default.toml").read_text()
#: Every case gets at most this long (a refusal takes a second; a case that runs is a failure).
TIMEOUT_S = 120


@dataclass(frozen=True)
class Case:
    """One command line, the files it is given and what must come of it."""

    name: str
    args: list[str]
    files: dict[str, str] = field(default_factory=dict)
    status: int = 2
    #: Words the one-line error must hold (the file or flag, what is wrong).
    needles: tuple[str, ...] = ()
    #: A further check on the scratch folder and the output (None: nothing to check).
    check: Callable[[Path, str], str] | None = None


def _load(**replace: str) -> str:
    """The example load with whole lines replaced: key -> new line."""
    lines = LOAD.splitlines()
    for key, new in replace.items():
        lines = [new if line.split("=")[0].strip() == key else line for line in lines]
    return "\n".join(lines) + "\n"


def _bundle(keys: str) -> str:
    """The example load with its bundle given by these keys instead of its preset."""
    return LOAD.replace('[bundle]\npreset = "PET6x1.5L"', f"[bundle]\n{keys}")


def _escaped(_: Path, out: str) -> str:
    return "" if "\x1b" not in out else "an escape code reached the terminal"


def _recording_made(folder: Path, _: str) -> str:
    return "" if (folder / "rec" / "profile.csv").exists() else "no recording written"


def _cycle_limit_named(_: Path, out: str) -> str:
    last = out.strip().splitlines()[-1] if out.strip() else ""
    return "" if "cycle-time limit" in last else f"the answer does not name the limit: {last!r}"


CASES = [
    # outputs found unusable before any work, inputs never overwritten
    Case("simulate --json into a folder", ["simulate", "L.toml", "--level", "0.2", "--json", "d"],
         {"L.toml": LOAD, "d/.keep": ""}, needles=("--json", "folder")),
    Case("simulate --plot under /proc", ["simulate", "L.toml", "--level", "0.2", "--plot",
                                         "/proc/x.png"], {"L.toml": LOAD}, needles=("--plot",)),
    Case("simulate --json onto its input", ["simulate", "L.toml", "--level", "0.2", "--json",
                                            "L.toml"], {"L.toml": LOAD}, needles=("--json",)),
    Case("recommend --json into a folder", ["recommend", "L.toml", "--json", "d"],
         {"L.toml": LOAD, "d/.keep": ""}, needles=("--json",)),
    Case("recommend --workers 1000", ["recommend", "L.toml", "--workers", "1000"],
         {"L.toml": LOAD}, needles=("--workers",)),
    Case("recommend --resume without a checkpoint", ["recommend", "L.toml", "--resume",
                                                     "--checkpoint", "none.json"],
         {"L.toml": LOAD}, needles=("checkpoint",)),
    Case("recommend --ray-address without Ray's client", ["recommend", "L.toml", "--backend",
                                                         "ray", "--ray-address", "ray://x:1"],
         {"L.toml": LOAD}, needles=("ray",)),
    Case("recommend --method ppo with a bad zip", ["recommend", "L.toml", "--method", "ppo",
                                                  "--policy", "p.zip"],
         {"L.toml": LOAD, "p.zip": "not a zip"}, needles=("p.zip",)),
    Case("recommend --method ppo --rounds 1 --budget 8 (a search's flag, no search)",
         ["recommend", "L.toml", "--method", "ppo", "--policy", "p.zip", "--rounds", "1",
          "--budget", "8"],
         {"L.toml": LOAD, "p.zip": "not a zip"}, needles=("--budget", "search")),
    Case("train --out holding an earlier run", ["train", "--out", "run", "--timesteps", "1"],
         {"run/log.csv": "timesteps\n"}, needles=("--out", "earlier")),
    Case("train --resume with no run to resume", ["train", "--out", "run", "--resume"],
         {"run/log.csv": "timesteps\n"}, needles=("--resume", "no run to resume")),
    Case("train --resume from a corrupt checkpoint", ["train", "--out", "run", "--resume"],
         {"run/log.csv": "timesteps\n", "run/checkpoints/policy_512_steps.zip": "not a zip"},
         needles=("policy_512_steps.zip", "policy")),
    Case("train --envs 100000", ["train", "--out", "run", "--envs", "100000"],
         needles=("--envs",)),
    Case("train --material-weight -1", ["train", "--out", "run", "--material-weight", "-1"],
         needles=("--material-weight",)),
    Case("train --log-std-init 3", ["train", "--out", "run", "--log-std-init", "3"],
         needles=("--log-std-init",)),
    Case("train --calibration with a spread no policy observes",
         ["train", "--out", "run", "--calibration", "c.json"],
         {"c.json": '{"friction": {"pallet_bundle": {"static": 0.5, "kinetic": 0.4, '
                    '"static_std": 3.0, "kinetic_std": 0.01, "identified": true}}}'},
         needles=("c.json", "friction.pallet_bundle.static_std")),
    Case("simulate --level abc", ["simulate", "L.toml", "--level", "abc"], {"L.toml": LOAD},
         needles=("--level", "abc")),
    Case("simulate --hours-since-wrapping -1", ["simulate", "L.toml", "--wrap", "W.toml",
                                                "--hours-since-wrapping", "-1"],
         {"L.toml": LOAD, "W.toml": WRAP}, needles=("--hours-since-wrapping",)),
    Case("recommend --target-long 1.5", ["recommend", "L.toml", "--target-long", "1.5"],
         {"L.toml": LOAD}, needles=("--target-long",)),
    Case("simulate --samples 0", ["simulate", "L.toml", "--samples", "0"], {"L.toml": LOAD},
         needles=("--samples",)),
    # impossible or malformed load units, wraps and calibrations
    Case("load: NaN friction", ["simulate", "L.toml"],
         {"L.toml": _load(sled_pallet="sled_pallet = { static = nan, kinetic = 0.4 }")},
         needles=("L.toml", "sled_pallet")),
    Case("load: a million layers", ["simulate", "L.toml"],
         {"L.toml": _load(layers="layers = 1000000")}, needles=("L.toml", "layers")),
    Case("load: 200 layers (66 m, 30 t)", ["simulate", "L.toml"],
         {"L.toml": _load(layers="layers = 200")}, needles=("L.toml",)),
    Case("load: a 1 mm bundle", ["simulate", "L.toml"],
         {"L.toml": _bundle("length_m = 0.001\nwidth_m = 0.001\nheight_m = 0.001\n"
                            "mass_kg = 0.001")},
         needles=("L.toml", "bundle")),
    Case("load: a 1e-9 m bundle", ["simulate", "L.toml"],
         {"L.toml": _bundle("length_m = 1e-9\nwidth_m = 1e-9\nheight_m = 1e-9\nmass_kg = 1.0")},
         needles=("L.toml", "bundle")),
    Case("load: 1000 kg of bundles on a half pallet (it carries 500)", ["simulate", "L.toml"],
         {"L.toml": LOAD.replace('preset = "EUR"', 'preset = "EPAL6"').replace(
             '[bundle]\npreset = "PET6x1.5L"', '[bundle]\npreset = "PET6x1.5L"\nmass_kg = 83.4')},
         needles=("L.toml", "bundle.mass_kg", "500 kg")),
    Case("load: a pallet said to carry 1e9 kg", ["simulate", "L.toml"],
         {"L.toml": LOAD.replace('preset = "EUR"', 'preset = "EUR"\nsafe_load_kg = 1e9')},
         needles=("L.toml", "pallet.safe_load_kg")),
    Case("load: unknown key", ["simulate", "L.toml"],
         {"L.toml": LOAD.replace("[stack]", "[stack]\nlayrs = 2")}, needles=("L.toml", "layrs")),
    Case("wrap: negative tension", ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": WRAP.replace("bottom_tension_n = 800.0",
                                                  "bottom_tension_n = -800.0")},
         needles=("W.toml", "bottom_tension_n")),
    Case("wrap: paper asked to rope", ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": WRAP.replace("[program]", "[program]\nroping = true")},
         needles=("W.toml", "roping")),
    Case("wrap: a custom card's shear ratio in percent",
         ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": WRAP.replace(
             'material = "kraft"', "[material]\ngrammage_kg_m2 = 0.09\nstiffness_n_per_m = 4e5\n"
             "yield_strain = 0.008\nbreak_strain = 0.07\nkind = 'paper'\nshear_ratio = 25")},
         needles=("W.toml", "shear_ratio")),
    Case("wrap: a spiral of a hundred layers (overlap 0.99)",
         ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": WRAP.replace("up_overlap = 0.5", "up_overlap = 0.99")},
         needles=("W.toml", "up_overlap")),
    Case("CAL.json with a key given twice", ["simulate", "L.toml", "--calibration", "c.json"],
         {"L.toml": LOAD, "c.json": '{"friction": {}, "friction": {}}'},
         needles=("c.json", "friction")),
    Case("CAL.json that calibrates nothing", ["simulate", "L.toml", "--calibration", "c.json"],
         {"L.toml": LOAD, "c.json": "{}"}, needles=("c.json", "calibrates nothing")),
    Case("CAL.json whose acceptance says a recording was unexplained by -1 m",
         ["simulate", "L.toml", "--calibration", "c.json"],
         {"L.toml": LOAD, "c.json": '{"friction": {"sled_pallet": {"static": 0.4, '
                                    '"kinetic": 0.3}}, "acceptance": '
                                    '{"unexplained_rms_m": -1}}'},
         needles=("c.json", "acceptance.unexplained_rms_m")),
    Case("CAL.json with a friction spread of a million", ["simulate", "L.toml", "--calibration",
                                                          "c.json", "--samples", "2"],
         {"L.toml": LOAD, "c.json": '{"friction": {"sled_pallet": {"static": 0.4, '
                                    '"kinetic": 0.3, "kinetic_std": 1e6}}}'},
         needles=("c.json", "friction.sled_pallet.kinetic_std")),
    Case("CAL.json truncated", ["simulate", "L.toml", "--calibration", "c.json"],
         {"L.toml": LOAD, "c.json": '{"friction": {"sled_pallet": {"static": 0.4'},
         needles=("c.json",)),
    # recordings
    Case("synth --size 100000x100000", ["synth", "L.toml", "--out", "rec", "--size",
                                        "100000x100000"], {"L.toml": LOAD}, needles=("--size",)),
    Case("synth --fps 100000", ["synth", "L.toml", "--out", "rec", "--fps", "100000"],
         {"L.toml": LOAD}, needles=("--fps",)),
    Case("synth --fps 29.97 (containers store whole rates)",
         ["synth", "L.toml", "--out", "rec", "--fps", "29.97"], {"L.toml": LOAD},
         needles=("fps", "whole")),
    Case("synth --level 5", ["synth", "L.toml", "--out", "rec", "--level", "5"],
         {"L.toml": LOAD}, needles=("--level",)),
    Case("synth --fps 0.5 (no container stores it)", ["synth", "L.toml", "--out", "rec",
                                                       "--fps", "0.5"],
         {"L.toml": LOAD}, needles=("--fps",)),
    Case("synth --seed -1", ["synth", "L.toml", "--out", "rec", "--seed", "-1"],
         {"L.toml": LOAD}, needles=("--seed",)),
    Case("simulate --profile with a 200 kB field", ["simulate", "L.toml", "--profile", "p.csv"],
         {"L.toml": LOAD, "p.csv": "t_s,accel_mps2\n" + "1" * 200_000 + ",0\n"},
         needles=("p.csv", "line 2")),
    Case("simulate a load in millimetres", ["simulate", "L.toml", "--level", "0.2"],
         {"L.toml": _bundle("length_m = 280\nwidth_m = 190\nheight_m = 330\nmass_kg = 9.3")},
         needles=("L.toml", "millimetres?")),
    Case("simulate a friction coefficient in percent", ["simulate", "L.toml", "--level", "0.2"],
         {"L.toml": LOAD.replace("static = 0.45", "static = 45")},
         needles=("L.toml", "friction.sled_pallet.static", "not a percentage")),
    Case("simulate --profile saved by a European-locale spreadsheet",
         ["simulate", "L.toml", "--profile", "p.csv"],
         {"L.toml": LOAD, "p.csv": "t_s;accel_mps2\n0,0;0,0\n0,1;2,5\n0,6;2,5\n"},
         needles=("p.csv", "separated by ';'")),
    Case("synth --out under /proc", ["synth", "L.toml", "--out", "/proc/rec"], {"L.toml": LOAD},
         needles=("/proc/rec",)),
    Case("track a folder without a video", ["track", "rec"], {"rec/setup.toml": ""},
         needles=("rec",)),
    Case("synth a tiny 64x64 video", ["synth", "L.toml", "--out", "rec", "--size", "64x64",
                                      "--fps", "5"], {"L.toml": LOAD}, status=0,
         check=_recording_made),
    Case("recommend --max-cycle-s 1 (no program that fast)",
         ["recommend", "L.toml", "--max-cycle-s", "1", "--budget", "3", "--samples", "1"],
         {"L.toml": LOAD}, status=1, check=_cycle_limit_named),
    Case("setup.toml with the markers' side in millimetres", ["track", "rec"],
         {"rec/setup.toml": '[recording]\nfps = 20\n[camera]\npx_per_m = 500.0\n'
                            'origin_px = [100.0, 900.0]\n[markers]\ndictionary = "DICT_4X4_50"\n'
                            'size_m = 75\n'},
         needles=("setup.toml", "markers.size_m", "millimetres?")),
    Case("calibrate the same take twice", ["calibrate", "rec", "./rec", "--out", "c.json"],
         {"rec/setup.toml": ""}, needles=("DIR", "given twice")),
    # found by a new user's walk through the README (2026-11-27)
    Case("recommend --checkpoint naming the user's own notes",
         ["recommend", "L.toml", "--checkpoint", "notes.txt"],
         {"L.toml": LOAD, "notes.txt": "my lab notes\n"}, needles=("notes.txt", "--checkpoint")),
    Case("simulate --json onto the report's page",
         ["simulate", "L.toml", "--level", "0.2", "--report", "R", "--json", "R/report.html"],
         {"L.toml": LOAD, "R/keep.txt": ""}, needles=("--json", "--report")),
    Case("wrap: a web with neither program nor bands", ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": 'material = "kraft"\nweb_width_m = 0.5\n'},
         needles=("W.toml", "program")),
    Case("load: two bundles at one explicit position", ["simulate", "L.toml"],
         {"L.toml": _load(pattern='pattern = "explicit"\npositions = [[0.2, 0.1], [0.2, 0.1]]')},
         needles=("L.toml", "positions[1]")),
    Case("simulate --hours-since-wrapping 1e9", ["simulate", "L.toml", "--wrap", "W.toml",
                                                 "--hours-since-wrapping", "1e9"],
         {"L.toml": LOAD, "W.toml": WRAP}, needles=("--hours-since-wrapping",)),
    Case("simulate --lev 0.2 (a flag abbreviated)", ["simulate", "L.toml", "--lev", "0.2"],
         {"L.toml": LOAD}, needles=("--lev",)),
    # found by a fuzz of every example's fields (2026-12-01): each was taken, and filled the
    # memory or took centuries
    Case("wrap: a 1 µm web", ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": WRAP.replace("web_width_m = 0.5", "web_width_m = 1e-6")},
         needles=("W.toml", "web_width_m")),
    Case("wrap: a band 1e9 m tall", ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": 'material = "kraft"\nweb_width_m = 0.5\n[[band]]\n'
                                    'from_m = 0.0\nto_m = 1e9\nlayers = 2\ntension_n = 200.0\n'},
         needles=("W.toml", "band[0].to_m")),
    Case("wrap: 0.2 rpm (per second)", ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": WRAP.replace("[program]", "[program]\nrpm = 0.2")},
         needles=("W.toml", "program.rpm", "per minute")),
    Case("wrap: a carriage at 1e-9 m/s", ["simulate", "L.toml", "--wrap", "W.toml"],
         {"L.toml": LOAD, "W.toml": WRAP + "\n[machine]\ncarriage_speed_mps = 1e-9\n"},
         needles=("W.toml", "machine.carriage_speed_mps")),
    Case("a LOAD.toml saved with a byte-order mark", ["simulate", "L.toml", "--level", "0.2"],
         {"L.toml": "\ufeff" + LOAD}, status=0),
    Case("a load name with escape codes", ["simulate", "L.toml", "--level", "0.2"],
         {"L.toml": LOAD.replace('name = "6x1.5 L PET bundles, 2 layers, columnar"',
                                 'name = "evil\\u001b[2J"')},
         status=0, check=_escaped),
]


def run(case: Case) -> tuple[bool, str, float]:
    """Run one case in a fresh scratch folder; (as promised, what was wrong, seconds)."""
    with tempfile.TemporaryDirectory(prefix="wrapbench-sweep-") as tmp:
        folder = Path(tmp)
        for name, text in case.files.items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_text(text)
        before = {p.relative_to(folder): p.read_bytes() if p.is_file() else None
                  for p in folder.rglob("*")}
        t0 = time.perf_counter()
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        try:
            proc = subprocess.run([sys.executable, "-m", "recommender.cli", *case.args],
                                  cwd=folder, capture_output=True, text=True, env=env,
                                  timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            return False, f"still running after {TIMEOUT_S} s", TIMEOUT_S
        seconds = time.perf_counter() - t0
        return _judge(case, proc, folder, before, seconds)


def _judge(case: Case, proc: subprocess.CompletedProcess, folder: Path,
           before: dict[Path, bytes | None], seconds: float) -> tuple[bool, str, float]:
    lines = proc.stderr.strip().splitlines()
    if proc.returncode != case.status:
        last = lines[-1] if lines else ""
        return False, f"exit {proc.returncode}, expected {case.status}: {last[:120]}", seconds
    if "Traceback" in proc.stderr:
        return False, "traceback on stderr", seconds
    if case.status == 2:
        errors = [line for line in lines if line.startswith("wrapbench")]
        if len(errors) != 1:
            return False, f"{len(lines)} lines on stderr", seconds
        missing = [n for n in case.needles if n.lower() not in errors[0].lower()]
        if missing:
            return False, f"message lacks {missing}: {errors[0][:120]}", seconds
        after = {p.relative_to(folder): p.read_bytes() if p.is_file() else None
                 for p in folder.rglob("*")}
        if after != before:
            changed = sorted(p for p in after.keys() | before.keys()
                             if after.get(p) != before.get(p))
            return False, f"wrote {changed}", seconds
        return True, errors[0][:110], seconds
    problem = case.check(folder, proc.stdout) if case.check else ""
    return not problem, problem or "as promised", seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="only cases whose name contains this")
    args = parser.parse_args()
    cases = [c for c in CASES if args.k in c.name]
    failed = 0
    print("| case | exit | ok | s | message or problem |\n|---|---|---|---|---|")
    for case in cases:
        ok, text, seconds = run(case)
        failed += not ok
        print(f"| {case.name} | {case.status} | {'yes' if ok else 'NO'} | {seconds:.1f} | "
              f"{text.replace('|', '/')} |", flush=True)
    print(f"{len(cases) - failed} of {len(cases)} cases as promised")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

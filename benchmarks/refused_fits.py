"""What the fits `calibrate` refuses would have recommended, checked on the true unit.

The README's decision 3 asks whether a calibration whose take its replays leave unexplained
should be refused (today) or written flagged. This answers the question a user asks of it:
would such a calibration have led to a program that fails? On `bench_calibrate`'s columnar2
takes (the 2-layer example's friction drawn with jitter, hidden from the fit), each fit seed is
run as a user would, `wrapbench calibrate ... --max-residual-mm 35` (the default 10 mm refuses
five of the six: docs/calibration.md); then `wrapbench recommend` answers with each CAL.json,
with the true friction and with the load file's own, and `wrapbench simulate --eumos` tests
every answer on the true unit, both sides, 16 h after wrapping, as `recommend` verifies; a
holding answer's cell gives the largest share of a criterion's limit any level reached.

    python -m benchmarks.refused_fits [--seed 0 1 2 3 4 5] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_calibrate import CASES, observation
from calibration.recording import Truth
from wrapenv.eumos import EUMOS_CRITERIA
from wrapenv.load import Friction, FrictionPair, LoadUnit

#: The bound the fits are accepted under (their unexplained takes: 10.8-30.1 mm).
MAX_RESIDUAL_MM = 35.0
#: (material, target g): the search's default, a road rule's forward level, and film.
ASKS = (("kraft", 0.5), ("kraft", 0.8), ("lldpe", 0.5))
HOURS = 16.0


def wrapbench(*argv: str) -> subprocess.CompletedProcess:
    """One command as a user types it; its exit status, output and files are what is read (a
    crash, whose exit status 1 would read as "nothing passed", is raised)."""
    done = subprocess.run([sys.executable, "-m", "recommender.cli", *argv],
                          capture_output=True, text=True)
    if "Traceback" in done.stderr:
        raise RuntimeError(f"wrapbench {' '.join(argv)} crashed:\n{done.stderr[-2000:]}")
    return done


#: `recommend`'s reasons for recommending nothing (recommender/recommend.py), as a cell says them.
NONE_BECAUSE = {"no program recommended": "its passes failed their verification",
                "no program passed": "nothing passed",
                "no program within the cycle-time limit": "every candidate too slow"}


def why_none(stdout: str) -> str:
    """Why `recommend` recommended nothing, and in which round, from the line it printed."""
    line = next((ln for ln in stdout.splitlines() if ln.startswith("no program")), "")
    reason = next((v for k, v in NONE_BECAUSE.items() if line.startswith(k)), "exit 1")
    return reason + (" in round 2" if "in round 2" in line else "")


def true_load(folder: Path, truth: Truth, out: Path) -> Path:
    """The take's load file with the friction the take was made with (to 3 decimals)."""
    pairs = {k: FrictionPair(round(v["static"], 3), round(v["kinetic"], 3))
             for k, v in truth.params["friction"].items()}
    unit = LoadUnit.from_toml(folder / "load.toml")
    out.write_text(unit.with_friction(Friction(**pairs)).to_toml())
    return out


def answer(work: Path, name: str, load: Path, material: str, target: float,
           calibration: Path | None, checked_on: Path) -> str:
    """`recommend`'s program (mass) and how it fares on the true unit, as one table cell."""
    stem = work / f"{name}-{material}-{target}"
    cal = ["--calibration", str(calibration)] if calibration else []
    done = wrapbench("recommend", str(load), "--material", material, "--target", str(target),
                     "--json", f"{stem}.json", "--wrap-out", f"{stem}.toml", *cal)
    if done.returncode == 1:
        return f"none ({why_none(done.stdout)})"
    if done.returncode != 0:
        return f"none (exit {done.returncode})"
    mass = json.loads(Path(f"{stem}.json").read_text())["material_used"]["mass_kg"]
    worst = 0.0
    for side in ("long", "short"):
        verdict = Path(f"{stem}-{side}.json")
        code = wrapbench("simulate", str(checked_on), "--wrap", f"{stem}.toml", "--eumos",
                         "--target", str(target), "--orientation", side,
                         "--hours-since-wrapping", str(HOURS), "--json",
                         str(verdict)).returncode
        if code != 0:
            return f"{mass:.3f} kg, FAILS the true unit ({side} side)"
        run = json.loads(verdict.read_text())
        worst = max(worst, *(level[c.figure] / c.limit_m(run["load_height_m"])
                             for level in run["levels"] for c in EUMOS_CRITERIA))
    return f"{mass:.3f} kg, holds ({worst:.0%} of a limit)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    takes = [t.folder() for t in CASES["columnar2"][0]]
    # made and tracked into the cache if missing; the takes share one draw of friction
    truths = [observation(take)[1] for take in CASES["columnar2"][0]]
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        truth = true_load(takes[0], truths[0], work / "true.toml")
        nominal = takes[0] / "load.toml"
        rows: list[tuple[str, Path, Path | None]] = [("true friction", truth, None),
                                                     ("the load file's", nominal, None)]
        for seed in args.seed:
            cal = work / f"cal-{seed}.json"
            code = wrapbench("calibrate", *map(str, takes), "--out", str(cal), "--seed",
                             str(seed), "--workers", str(args.workers),
                             "--max-residual-mm", str(MAX_RESIDUAL_MM)).returncode
            rows.append((f"fit seed {seed}" if code == 0 else f"fit seed {seed} (exit {code})",
                         nominal, cal if code == 0 else None))
        print("| friction | " + " | ".join(f"{m} {g} g" for m, g in ASKS) + " |")
        print("|---" * (len(ASKS) + 1) + "|")
        for name, load, calibration in rows:
            if name.startswith("fit") and calibration is None:
                print(f"| {name} |" + " |" * len(ASKS), flush=True)
                continue
            cells = [answer(work, name.replace(" ", "_"), load, m, g, calibration, truth)
                     for m, g in ASKS]
            print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()

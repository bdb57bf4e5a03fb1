"""Speed and accuracy of `wrapbench track` on a synthetic 1920x1200 recording.

The recording (2-layer PET example at 0.4 g, second layer sliding) is synthesised once into a
cache folder; its frame rate is chosen so the test spans about 200 frames. Printed: frames,
decode-only fps, track fps (best of `--repeat` runs, whole pipeline: decode, ROI, detection,
tracking), and the per-object displacement error against truth.json.

    python -m benchmarks.bench_track [--size 1920 1200] [--frames 200] [--cache DIR]
"""

from __future__ import annotations

import argparse
import hashlib
import tempfile
import time
from pathlib import Path

import cv2

from calibration.recording import Recording, Truth
from calibration.synth import synthesize
from calibration.track import track
from calibration.trajectories import error_vs_truth
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat


def _code_digest() -> str:
    """The bench's and the filming's source, digested: a recording made by other code is not
    its truth (a stop bar moved 1 mm changed every take; 2026-11-27)."""
    root = Path(__file__).resolve().parent.parent
    sources = sorted([*root.glob("wrapenv/**/*.py"), *root.glob("calibration/**/*.py")])
    return hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()[:12]


#: Recordings made once per parameter set and per version of the code that makes them.
CACHE = Path(tempfile.gettempdir()) / "wrapbench-bench" / _code_digest()
#: Seconds a synthetic test lasts at 20 fps (pre-roll included), measured on the examples; used
#: to pick the frame rate that gives the wanted number of frames.
PROBE_FPS = 20.0


def cached_recording(load: str, level_g: float, size: tuple[int, int], *, wrap: str | None = None,
                     frames: int | None = None, cache: Path = CACHE) -> Recording:
    """A synthetic recording of `load` (and `wrap`) at `level_g`, made once per parameter set.
    With `frames`, the frame rate is set so the recording has about that many frames."""
    unit = LoadUnit.from_toml(load)
    fmt = WrapFormat.from_toml(wrap, unit.layout().load_height_m) if wrap else None
    fps = PROBE_FPS
    if frames is not None:
        probe = cached_recording(load, level_g, (480, 300), wrap=wrap, cache=cache)
        # whole frames per second: an AVI stores its rate as an integer, and `Recording.read`
        # refuses a setup.toml whose rate the video does not have (62.5 against 62)
        fps = round(PROBE_FPS * frames / _frame_count(probe))
    tag = f"{Path(load).stem}-{Path(wrap).stem if wrap else 'bare'}-{level_g}g-{size[0]}x{size[1]}"
    folder = cache / f"{tag}-{fps:g}fps"
    if (folder / "truth.json").exists():
        return Recording.read(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    return synthesize(unit, folder, wrap=fmt, level_g=level_g, size=size, fps=fps)


def _frame_count(rec: Recording) -> int:
    cap = cv2.VideoCapture(str(rec.video))
    try:
        return int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()


def decode_fps(rec: Recording) -> float:
    cap = cv2.VideoCapture(str(rec.video))
    start, n = time.perf_counter(), 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(1920, 1200))
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--tracker", default="ncc+flow")
    parser.add_argument("--cache", type=Path, default=CACHE)
    args = parser.parse_args()
    rec = cached_recording("examples/pet_2layer_columnar.toml", 0.4, tuple(args.size),
                           frames=args.frames, cache=args.cache)
    n = _frame_count(rec)
    print(f"recording {rec.folder} ({n} frames, {rec.fps:g} fps, {rec.px_per_m:.1f} px/m)")
    print(f"decode only: {decode_fps(rec):.1f} fps")
    best = float("inf")
    for _ in range(args.repeat):
        start = time.perf_counter()
        result = track(rec, tracker=args.tracker)
        best = min(best, time.perf_counter() - start)
    print(f"track ({args.tracker}): {n / best:.1f} fps ({best:.2f} s for {n} frames)")
    for w in result.warnings:
        print("warning:", w)
    errors = error_vs_truth(result.trajectories, Truth.read(rec.folder).objects)
    print(f"{'object':8} {'rms mm':>7} {'max mm':>7} {'start mm':>8} frames")
    for name, e in sorted(errors.items()):
        print(f"{name:8} {1e3 * e.rms_m:7.2f} {1e3 * e.max_m:7.2f} {1e3 * e.offset_m:8.2f}"
              f" {e.frames}")


if __name__ == "__main__":
    main()

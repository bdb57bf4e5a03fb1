"""A recording is synthesised and tracked alike on every x86-64 processor
(`calibration/__init__.py`), and fitted alike (`calibration.replay.VALUE_DECIMALS`), so a
calibration writes the same CAL.json wherever it runs."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

from calibration.synth import synthesize
from tests.calibration.conftest import SLIDE_BUDGET
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat

#: Synthesises two takes into a temporary folder and tracks them: the slide take (two bundles
#: sliding on the pallet) and the small unit wrapped in Kraft with markers on the web; prints
#: the digests of each video's bytes and of its tracked paths.
_TAKES = """
import hashlib, sys, tempfile
from pathlib import Path
from calibration.recording import Recording
from calibration.synth import synthesize
from calibration.track import track
from tests.calibration.conftest import QUARTER_PALLET_LOAD, SLIDE_LOAD, SLIDE_SYNTH, SYNTH
from wrapenv.load import LoadUnit
from wrapenv.wrap import WrapFormat
small = LoadUnit.from_dict(QUARTER_PALLET_LOAD)
wrap = WrapFormat.from_dict({"material": "kraft", "web_width_m": 0.5,
                             "band": [{"from_m": 0.0, "to_m": 0.78, "layers": 2,
                                       "tension_n": 100.0}]})
with tempfile.TemporaryDirectory() as folder:
    takes = {"slide": lambda out: synthesize(LoadUnit.from_dict(SLIDE_LOAD), out, **SLIDE_SYNTH),
             "wrapped": lambda out: synthesize(small, out, wrap=wrap, seed=4, **SYNTH)}
    for name, make in takes.items():
        out = Path(folder) / name
        make(out)
        paths = track(Recording.read(out)).trajectories
        out_csv = Path(folder) / (name + ".csv")
        paths.to_csv(out_csv)
        for data in ((out / "video.avi").read_bytes(), out_csv.read_bytes()):
            print(hashlib.sha256(data).hexdigest())
"""
#: Another processor, as far as OpenCV's, numpy's and OpenBLAS's own choice of code goes: no
#: AVX, AVX2, FMA or SSE4 in OpenCV, none of numpy's AVX loops, OpenBLAS's SSE3 kernels.
_ANOTHER_PROCESSOR = {
    "OPENCV_CPU_DISABLE": "AVX512_SKX,AVX512_COMMON,AVX2,FMA3,AVX,FP16,POPCNT,SSE4_2,SSE4_1",
    "NPY_DISABLE_CPU_FEATURES": "AVX512F AVX512CD AVX512_SKX AVX512_ICL AVX512_SPR AVX2 FMA3 "
                                "F16C AVX",
    "OPENBLAS_CORETYPE": "Prescott",
}


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"),
                    reason="the features disabled are named as x86-64's")
def test_processors_with_other_simd_synthesise_and_track_a_take_identically():
    """With OpenCV's code chosen per processor, the slide take's video and paths differed
    between these two (and the 2-layer example's 0.45 g take's paths by up to 81 mm)."""
    digests = []
    for extra in ({}, _ANOTHER_PROCESSOR):
        done = subprocess.run([sys.executable, "-c", _TAKES], env=os.environ | extra,
                              check=True, capture_output=True, text=True)
        digests.append(done.stdout.split())
    assert len(digests[0]) == 4
    assert digests[0] == digests[1]


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"),
                    reason="the features disabled are named as x86-64's")
def test_processors_with_other_simd_fit_the_same_calibration(slide_dir, tmp_path):
    """The same take and seed give the same CAL.json byte for byte where numpy's and
    OpenBLAS's arithmetic round their last bits otherwise (`replay.VALUE_DECIMALS`): the
    2-layer unit's fit of seed 5 ended with pallet-bundle's kinetic coefficient at 0.4355 on
    one and 0.4366 on the other before, the same fit's values 5e-13 apart once its path was
    the same."""
    written = []
    for k, extra in enumerate(({}, _ANOTHER_PROCESSOR)):
        out = tmp_path / f"cal{k}.json"
        subprocess.run([sys.executable, "-m", "recommender.cli", "calibrate", str(slide_dir),
                        "--out", str(out), "--budget", str(SLIDE_BUDGET), "--workers", "1"],
                       env=os.environ | extra, check=True, capture_output=True)
        written.append(out.read_bytes())
    assert b'"friction"' in written[0]
    assert written[0] == written[1]


def test_a_wrapped_take_is_drawn_the_same_every_time(tmp_path):
    """At full size OpenCV split the drawing of the web and its markers over its threads, and
    the split changed the rounding: two runs' videos differed by 1-2 grey levels in 30 of 64
    frames, and LLDPE's fitted stiffness with them (docs/calibration.md). At 960 x 600 and
    640 x 400 the threads' takes came out the same (2026-11-30), so the test draws at full size,
    at 5 fps: 16 frames, all alike by chance less than once in 10^4 at that rate (0.53^16), in a
    third of the time of 20 fps. The split is the machine's: on the forty-second session's, a
    draw without `opencv_threads(0)` came out the same at 5 and at 20 fps too."""
    load = LoadUnit.from_toml("examples/pet_2layer_columnar.toml")
    wrap = WrapFormat.from_toml("examples/wrap_lldpe_2layer.toml", load.layout().load_height_m)
    videos = []
    for run in ("a", "b"):
        rec = synthesize(load, tmp_path / run, wrap=wrap, level_g=0.7, size=(1920, 1200),
                         fps=5.0)
        videos.append(rec.video.read_bytes())
    assert videos[0] == videos[1]

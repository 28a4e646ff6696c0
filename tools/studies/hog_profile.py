"""HOG and ``Detector.detect`` time, this working tree against another git revision, interleaved.

    python -m tools.studies.hog_profile [--against HEAD] [--rounds 15] [--frames 6]

The HOG kernels of ``--against`` (``fastdet/features/_hog.py`` and ``_hog_kernels.py`` as
committed there) are loaded beside the working tree's as a separate module; then, in one
process, old and new take turns:

* HOG per band: ``hog_channels(band, ..., exact=False)`` on the colour-converted bands the
  default ``Detector()`` feeds it for test1.jpg (7 bands, 614 k pixels, 3 channels, 16
  orientations), split into cell histograms and block normalisation, ms per frame (sum
  over bands of each band's best ``time.thread_time``), 1 thread;
* ``Detector().detect`` on the test images (one frame per call, cycling), with the
  detector's ``hog_channels`` swapped for the old one or left as it is, at 1 and 2 Numba
  threads: best and median ms per frame over ``--rounds`` rounds of ``--frames`` frames
  each, the two versions alternating round by round (1 thread: the calling thread's CPU
  time, ``time.thread_time``, which other programs on the machine do not inflate; 2
  threads: wall time).

Both versions' outputs are compared before timing (cell histograms bit for bit, blocks to
1e-13 relative, every window's decision value to 1e-9). The machine is shared: read the
best figures; a median far above the best means other programs were running.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import cv2
import numba
import numpy as np

import fastdet.detect.detector as detector_module
from benchmarks.bench_hog import band_images
from fastdet.data import data_dir
from fastdet.detect import Detector, DetectStats
from fastdet.features import _hog as new_hog
from fastdet.features import _hog_kernels as new_k

REPO = Path(__file__).resolve().parent.parent


def load_old(rev: str, folder: Path):
    """``(_hog, _hog_kernels)`` modules of git revision ``rev``, importable beside the new ones."""
    def show(path: str) -> str:
        return subprocess.run(["git", "show", f"{rev}:{path}"], cwd=REPO, check=True,
                              capture_output=True, text=True).stdout

    kern = show("fastdet/features/_hog_kernels.py").replace("from .._numba import", "from fastdet._numba import")
    # revisions with parallel=True kernels import options fastdet._numba no longer has
    kern = kern.replace("from fastdet._numba import EXACT, EXACT_PARALLEL, REASSOC",
                        "from fastdet._numba import EXACT, REASSOC\nEXACT_PARALLEL = dict(EXACT, parallel=True)")
    hog = show("fastdet/features/_hog.py").replace("from . import _hog_kernels as _k",
                                                   "import old_hog_kernels as _k")
    (folder / "old_hog_kernels.py").write_text(kern)
    (folder / "old_hog.py").write_text(hog)
    sys.path.insert(0, str(folder))
    mods = []
    for name in ("old_hog_kernels", "old_hog"):
        spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
        mods.append(mod)
    return mods[1], mods[0]


def best_ms(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best * 1e3


def hog_split(hog_mod, k, bands, cfg, rounds: int) -> dict[str, float]:
    """ms per frame of HOG on ``bands``: whole, cell histograms only, normalisation only."""
    chans = np.arange(3, dtype=np.int64)
    o, c, b = cfg.orientations, cfg.pixels_per_cell, cfg.cells_per_block
    method = hog_mod.BLOCK_NORMS["L2-Hys"]
    bin_lut, mag_lut = hog_mod._luts(o)
    total = {"hog": 0.0, "cells": 0.0, "blocks": 0.0}
    for img in bands:
        n_cells = (img.shape[0] // c, img.shape[1] // c)
        ht = np.empty((n_cells[0], 3, n_cells[1], o))
        out = np.empty((n_cells[0] - b + 1, n_cells[1] - b + 1, 3, b * b * o))
        hist = ht.transpose(0, 2, 1, 3)

        def cells(img=img, ht=ht, hist=hist, n_rows=n_cells[0]):
            if hasattr(k, "cell_hists_u8"):  # one kernel over a range of cell rows
                k.cell_hists_u8(img, chans, False, 0, n_rows, c, c, bin_lut, mag_lut, ht)
                return
            for ci in range(n_rows):  # revisions before it
                k._cell_row_u8(img, chans, False, ci, c, c, bin_lut, mag_lut, hist)

        normalize = getattr(k, "normalize_blocks_fast", None) or k._normalize_rows_fast
        fns = {"hog": lambda img=img: hog_mod.hog_channels(img, o, c, b, channels=[0, 1, 2], exact=False),
               "cells": cells,
               "blocks": lambda ht=ht, out=out: normalize(ht, 0, out.shape[0], b, b, method, out)}
        for f in fns.values():
            f()
        for name, f in fns.items():
            total[name] += best_ms(f, rounds)
    return total


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--against", default="HEAD", help="git revision to compare with (default HEAD)")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--frames", type=int, default=6, help="frames per detect round")
    args = ap.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix="fastdet-old-hog-") as tmp:
        old_hog, old_k = load_old(args.against, Path(tmp))
        test_images = sorted((data_dir() / "test_images").glob("*.jpg"))
        frames = [cv2.imread(str(p)) for p in test_images][: args.frames]
        det = Detector()
        cfg = det.scorers[0].config
        bands = band_images(det, frames[0])
        kw = {"orientations": cfg.orientations, "pixels_per_cell": cfg.pixels_per_cell,
              "cells_per_block": cfg.cells_per_block, "channels": list(cfg.hog_channels), "exact": False}
        for img in bands:  # same blocks
            a, b = old_hog.hog_channels(img, **kw), new_hog.hog_channels(img, **kw)
            np.testing.assert_allclose(b, a, rtol=1e-13, atol=1e-15)
        numba.set_num_threads(1)
        # interleaved: old, new, old, new, ...
        res = {"old": [], "new": []}
        for _ in range(3):
            for name, (hm, km) in (("old", (old_hog, old_k)), ("new", (new_hog, new_k))):
                res[name].append(hog_split(hm, km, bands, cfg, max(args.rounds // 3, 3)))
        print(f"HOG per 1280x720 frame ({len(bands)} bands of test1.jpg, "
              f"{sum(i.shape[0] * i.shape[1] for i in bands)} px), 1 thread, best ms:")
        for part in ("hog", "cells", "blocks"):
            o_ = min(r[part] for r in res["old"])
            n_ = min(r[part] for r in res["new"])
            print(f"  {part:7s} old {o_:6.3f}  new {n_:6.3f}  ({o_ / n_:.2f}x)")

        def detect_round(use_old: bool, clock) -> float:
            detector_module.hog_channels = old_hog.hog_channels if use_old else new_hog.hog_channels
            try:
                t0 = clock()
                for f in frames:
                    det.detect(f)
                return (clock() - t0) * 1e3 / len(frames)
            finally:
                detector_module.hog_channels = new_hog.hog_channels

        # same decision values with either HOG
        for use_old in (True, False):
            detector_module.hog_channels = old_hog.hog_channels if use_old else new_hog.hog_channels
            st = DetectStats()
            det.detect(frames[0], stats=st)
            if use_old:
                ref = [d for _, _, d in st.bands]
            else:
                for a, b in zip(ref, (d for _, _, d in st.bands)):
                    np.testing.assert_allclose(b, a, rtol=0, atol=1e-9)
        detector_module.hog_channels = new_hog.hog_channels
        for n_threads in (1, 2):
            if n_threads > numba.config.NUMBA_NUM_THREADS:
                continue
            numba.set_num_threads(n_threads)
            cv2.setNumThreads(n_threads)
            # one thread: the bands run in this thread, so its CPU time is the work, unaffected by
            # other programs taking the core; two: wall time (the band threads overlap)
            clock = time.thread_time if n_threads == 1 else time.perf_counter
            detect_round(True, clock)
            detect_round(False, clock)
            times = {"old": [], "new": []}
            for _ in range(args.rounds):
                times["old"].append(detect_round(True, clock))
                times["new"].append(detect_round(False, clock))
            o_b, n_b = min(times["old"]), min(times["new"])
            what = "thread CPU" if n_threads == 1 else "wall"
            print(f"Detector().detect, {n_threads} thread(s), {what} ms per frame "
                  f"(best / median of {args.rounds} rounds "
                  f"of {len(frames)} frames): old {o_b:.2f} / {statistics.median(times['old']):.2f}  "
                  f"new {n_b:.2f} / {statistics.median(times['new']):.2f}  ({o_b / n_b:.2f}x)")
        det.close()


if __name__ == "__main__":
    main()

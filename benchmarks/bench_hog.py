"""HOG speed: fastdet vs scikit-image vs OpenCV on the detector's search band, and the
Numba start-up cost.

Run::

    python -m pytest benchmarks/bench_hog.py --benchmark-only
    python -m tools.studies.bench_hog_report             # the same figures as a markdown table

The band is the 1280x256 ROI ``y in [400, 656)`` of ``test_images/test1.jpg`` in LUV; all
three channels, 9 orientations, 8x8-pixel cells, 2x2-cell blocks:

* ``fastdet.hog_channels`` at 1 and 2 Numba threads (one call, all channels);
* ``skimage.feature.hog`` once per channel (the values fastdet reproduces);
* ``cv2.HOGDescriptor.compute`` once per channel, window = the ROI rounded to whole
  cells, 16-pixel blocks at an 8-pixel stride, 8-pixel cells, 9 bins (the same block
  grid; OpenCV's HOG interpolates and weights differently, so only the time compares).
  The channel planes are split beforehand (not timed).

Detector bands: ``hog_channels(..., exact=False)`` (the detector's HOG) on the 7 scaled
YCrCb bands the default ``Detector()`` feeds it for test1.jpg (16 orientations, 2x2-cell
blocks), at 1 thread; ``python -m tools.studies.hog_profile`` splits this into cell histograms and
block normalisation and compares it with another git revision.

Start-up: a fresh interpreter imports fastdet and calls ``hog_channels`` once, with
``NUMBA_CACHE_DIR`` pointing at an empty folder (cold: everything is compiled) and then
again with that folder filled (warm: machine code loaded from the on-disk cache).
"""
from __future__ import annotations

import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numba
import numpy as np
import pytest

from fastdet.data import data_dir
from fastdet.features._hog import hog_channels, hog_channels_batch

ROI_Y = (400, 656)
ORIENTATIONS, CELL, BLOCK = 9, 8, 2
GROUP = "HOG 1280x256 LUV band, 3 channels"
REPO = Path(__file__).resolve().parent.parent


# --------------------------------------------------------------------------------------
# helpers (also used by tools/studies/bench_hog_report.py)
# --------------------------------------------------------------------------------------
def load_roi(data: Path | None = None) -> np.ndarray:
    """The search band of test1.jpg in LUV, ``(256, 1280, 3)`` uint8, C-contiguous."""
    data = data_dir() if data is None else data
    frame = cv2.imread(str(data / "test_images" / "test1.jpg"))
    if frame is None:
        raise FileNotFoundError(f"test_images/test1.jpg not found in {data}")
    return np.ascontiguousarray(cv2.cvtColor(frame, cv2.COLOR_BGR2LUV)[ROI_Y[0]:ROI_Y[1]])


def run_fastdet(roi):
    return hog_channels(roi, ORIENTATIONS, CELL, BLOCK)


def run_skimage(roi):
    from skimage.feature import hog

    return [hog(roi[:, :, c], ORIENTATIONS, (CELL, CELL), (BLOCK, BLOCK), feature_vector=False)
            for c in range(roi.shape[2])]


def opencv_setup(roi):
    """(descriptor, channel planes) for ``run_opencv``."""
    rows = roi.shape[0] // CELL * CELL
    cols = roi.shape[1] // CELL * CELL
    desc = cv2.HOGDescriptor((cols, rows), (BLOCK * CELL, BLOCK * CELL), (CELL, CELL),
                             (CELL, CELL), ORIENTATIONS)
    planes = [np.ascontiguousarray(roi[:rows, :cols, c]) for c in range(roi.shape[2])]
    return desc, planes


def run_opencv(desc, planes):
    return [desc.compute(p) for p in planes]


def time_ms(fn, *args, repeat: int) -> tuple[float, float]:
    """``(median, min)`` milliseconds per call of ``fn(*args)`` over ``repeat`` calls, after
    a warm-up call."""
    fn(*args)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e3, min(times) * 1e3


@contextlib.contextmanager
def threads(n: int):
    """Numba and OpenCV at ``n`` threads inside the block."""
    if n > numba.config.NUMBA_NUM_THREADS:
        pytest.skip(f"needs {n} threads, NUMBA_NUM_THREADS={numba.config.NUMBA_NUM_THREADS}")
    before_nb, before_cv = numba.get_num_threads(), cv2.getNumThreads()
    numba.set_num_threads(n)
    cv2.setNumThreads(n)
    try:
        yield
    finally:
        numba.set_num_threads(before_nb)
        cv2.setNumThreads(before_cv)


_START_SCRIPT = """
import sys, time
t0 = time.perf_counter()
import numpy as np
from fastdet.features import _hog_kernels
from fastdet.features._hog import hog_channels
t1 = time.perf_counter()
roi = np.load(sys.argv[1])
t2 = time.perf_counter()
_hog_kernels._pairwise_leaf(np.ones(1), 0, 1)  # Numba's one-time set-up + a tiny kernel
t3 = time.perf_counter()
hog_channels(roi, %d, %d, %d)
t4 = time.perf_counter()
hog_channels(roi, %d, %d, %d)
t5 = time.perf_counter()
print('{"import_s": %%r, "numba_init_s": %%r, "first_call_s": %%r, "second_call_s": %%r}'
      %% (t1 - t0, t3 - t2, t4 - t3, t5 - t4))
""" % ((ORIENTATIONS, CELL, BLOCK) * 2)


def _start_run(roi_file: Path, cache_dir: Path, n_threads: int) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), NUMBA_NUM_THREADS=str(n_threads))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    out = subprocess.run([sys.executable, "-c", _START_SCRIPT, str(roi_file)], env=env,
                         capture_output=True, text=True, check=True, cwd=REPO)
    return json.loads(out.stdout.strip().splitlines()[-1])


def start_up_times(roi: np.ndarray, n_threads: int = 2) -> dict:
    """Seconds for a fresh process with an empty Numba cache (``cold_*``) and then with
    the cache it filled (``warm_*``): ``import_s`` (numpy, numba, fastdet._hog),
    ``numba_init_s`` (first call of a tiny cached kernel: Numba's one-time set-up that
    any first kernel call pays), ``first_call_s`` (first ``hog_channels`` on the band:
    compiling or loading its kernels, building the LUTs, starting threads) and
    ``second_call_s``."""
    with tempfile.TemporaryDirectory(prefix="fastdet-numba-") as tmp:
        tmp = Path(tmp)
        roi_file = tmp / "roi.npy"
        np.save(roi_file, roi)
        cold = _start_run(roi_file, tmp / "cache", n_threads)
        warm = _start_run(roi_file, tmp / "cache", n_threads)
    result = {f"cold_{k}": v for k, v in cold.items()}
    result.update({f"warm_{k}": v for k, v in warm.items()})
    return result


# --------------------------------------------------------------------------------------
# benchmarks
# --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def roi(data):
    return load_roi(data)


@pytest.mark.parametrize("n_threads", [1, 2])
def test_fastdet_hog_channels(benchmark, roi, n_threads):
    with threads(n_threads):
        run_fastdet(roi)  # compile / load from cache outside the timing
        benchmark.group = GROUP
        benchmark.extra_info["threads"] = n_threads
        benchmark(run_fastdet, roi)


@pytest.mark.parametrize("n_threads", [1, 2])
def test_opencv_hogdescriptor(benchmark, roi, n_threads):
    desc, planes = opencv_setup(roi)
    with threads(n_threads):
        benchmark.group = GROUP
        benchmark.extra_info["threads"] = n_threads
        benchmark(run_opencv, desc, planes)


def test_skimage_hog(benchmark, roi):
    pytest.importorskip("skimage")
    benchmark.group = GROUP
    benchmark.extra_info["threads"] = 1
    benchmark.pedantic(run_skimage, args=(roi,), rounds=3, iterations=1, warmup_rounds=1)


def band_images(det, frame: np.ndarray) -> list[np.ndarray]:
    """The scaled, colour-converted band images ``det.detect(frame)`` runs HOG on (also used
    by tools/studies/hog_profile.py)."""
    import fastdet.detect.detector as detector_module

    seen = []
    real = detector_module.hog_channels

    def spy(img, *args, **kwargs):
        seen.append(np.ascontiguousarray(img))
        return real(img, *args, **kwargs)

    detector_module.hog_channels = spy
    try:
        det.detect(frame)
    finally:
        detector_module.hog_channels = real
    return seen


def detector_bands(data: Path | None = None) -> list[np.ndarray]:
    """The band images the default ``Detector()`` runs HOG on for test1.jpg."""
    from fastdet.detect import Detector

    data = data_dir() if data is None else data
    det = Detector()
    try:
        return band_images(det, cv2.imread(str(data / "test_images" / "test1.jpg")))
    finally:
        det.close()


def test_fastdet_detector_bands(benchmark, data):
    """The detector's HOG of one 1280x720 frame: every default band, 1 thread."""
    from fastdet.config import FeatureConfig

    cfg = FeatureConfig()
    bands = detector_bands(data)

    def run():
        for img in bands:
            hog_channels(img, cfg.orientations, cfg.pixels_per_cell, cfg.cells_per_block,
                         channels=list(cfg.hog_channels), exact=False)

    with threads(1):
        run()
        benchmark.group = "HOG of the detector's 7 bands of a 1280x720 frame (exact=False)"
        benchmark.extra_info["threads"] = 1
        benchmark(run)


@pytest.mark.parametrize("n_threads", [1, 2])
def test_fastdet_batch_crops(benchmark, data, n_threads):
    """hog_channels_batch on 1,000 64x64 LUV crops (the training-set path)."""
    paths = sorted((data / "vehicles" / "KITTI_extracted").glob("*.png"))[:1000]
    crops = np.stack([cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2LUV) for p in paths])
    with threads(n_threads):
        hog_channels_batch(crops[:2], ORIENTATIONS, CELL, BLOCK)
        benchmark.group = "HOG batch of 1,000 64x64 LUV crops, 3 channels"
        benchmark.extra_info["threads"] = n_threads
        benchmark(hog_channels_batch, crops, ORIENTATIONS, CELL, BLOCK)


def test_numba_start_up(benchmark, roi):
    """Cold (empty NUMBA_CACHE_DIR) and warm start of a fresh process; the timing is
    both runs together, the split is in extra_info (and printed with -s)."""
    benchmark.group = "HOG Numba start-up (fresh process, import + first call)"
    result = benchmark.pedantic(start_up_times, args=(roi,), rounds=1, iterations=1)
    benchmark.extra_info.update({k: round(v, 4) for k, v in result.items()})
    print("\nHOG start-up:", ", ".join(f"{k}={v:.3f}s" for k, v in result.items()))
    assert result["warm_first_call_s"] < result["cold_first_call_s"]

"""``Detector.detect`` side by side with OpenCV's C++ HOG detector on the same bands.

Run::

    python -m pytest benchmarks/bench_opencv.py --benchmark-only
    python -m tools.studies.bench_report --only opencv        # the same figures as a markdown table

What is compared, on the six ``test_images/*.jpg`` 1280x720 frames (cycled, one per call):

* ``fastdet``: ``Detector(oncoming=None).detect`` — the bundled main model over the default
  search (its 7 bands, windows 2 cells = 16 px apart in each scaled band): crop, resize,
  YCrCb, 3-channel HOG (16 orientations), spatial bins, colour histograms, 12,576 weights a
  window, decision values of every window, the positive windows as boxes;
* ``fastdet stride 8``: the same with ``cells_per_step=1`` (windows 8 px apart);
* ``OpenCV stride S``: ``cv2.HOGDescriptor((64, 64), (16, 16), (8, 8), (8, 8), 9,
  nlevels=1).detectMultiScale(band, winStride=(S, S), padding=(0, 0), groupThreshold=0)``
  on each of the same 7 bands, cut and resized exactly as fastdet does
  (``fastdet.detect.bands.scaled_band``, in the timing): one scale per call, so OpenCV scores
  exactly the band's 64x64 windows S px apart — Dalal-Triggs HOG (gradient of the strongest
  colour channel, 9 bins with trilinear voting, Gaussian block weights, L2-Hys) and 1,764
  weights a window (a fixed random linear model: the time does not depend on it).

At 2 threads both spread the bands over 2 Python threads, biggest first (fastdet's
``Detector`` does this itself; for OpenCV the benchmark does it: one ``detectMultiScale``
level runs on one thread). Each configuration is timed in interleaved rounds, so a burst of
load from another program hits all of them alike.
"""
from __future__ import annotations

import itertools
import os
import statistics
import time
from concurrent.futures import ThreadPoolExecutor

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before Numba's OpenMP layer starts

import cv2  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from benchmarks.bench_detector import load_frames  # noqa: E402
from benchmarks.bench_hog import threads  # noqa: E402
from fastdet.config import SearchConfig  # noqa: E402
from fastdet.detect import Detector  # noqa: E402
from fastdet.detect.bands import scaled_band  # noqa: E402

GROUP = "Detector.detect vs OpenCV HOGDescriptor.detectMultiScale, 1280x720, the 7 main bands"
FRAME_SHAPE = (720, 1280)
#: (label, kind, stride px) of every compared configuration
CASES = (("fastdet", "fastdet", 16), ("fastdet stride 8", "fastdet", 8),
         ("OpenCV stride 8", "opencv", 8), ("OpenCV stride 16", "opencv", 16))


class OpenCVBands:
    """OpenCV's HOG detector over the bands of ``Detector(oncoming=None)``'s default search (see
    the module docstring); ``detect(frame)`` returns the windows above 0 of every band."""

    def __init__(self, stride: int, det: Detector | None = None):
        det = det if det is not None else Detector(oncoming=None)
        self.geos = sorted(det.geometries(FRAME_SHAPE), key=lambda g: -g.scaled_w * g.scaled_h)
        self.stride = stride
        self.hog = cv2.HOGDescriptor((64, 64), (16, 16), (8, 8), (8, 8), 9, 1, -1.0,
                                     cv2.HOGDescriptor_L2Hys, 0.2, False, 1)  # nlevels=1: one scale
        n = self.hog.getDescriptorSize()
        w = np.random.default_rng(0).normal(size=n) * 0.01
        self.hog.setSVMDetector(np.concatenate([w, [-1.0]]).astype(np.float32))
        self._pool: ThreadPoolExecutor | None = None
        self._pool_size = 0

    @property
    def n_windows(self) -> int:
        s = self.stride
        return sum(((g.scaled_w - 64) // s + 1) * ((g.scaled_h - 64) // s + 1) for g in self.geos)

    def _band(self, frame, geo):
        img = scaled_band(frame, geo)
        rects, _ = self.hog.detectMultiScale(img, hitThreshold=0.0, winStride=(self.stride, self.stride),
                                             padding=(0, 0), scale=1.05, groupThreshold=0)
        return rects

    def detect(self, frame: np.ndarray, n_threads: int = 1) -> list:
        if n_threads < 2:
            return [self._band(frame, g) for g in self.geos]
        if self._pool_size != n_threads:
            if self._pool is not None:
                self._pool.shutdown()
            self._pool, self._pool_size = ThreadPoolExecutor(n_threads), n_threads
        return list(self._pool.map(lambda g: self._band(frame, g), self.geos))


def make_case(kind: str, stride: int):
    """``(callable(frame, n_threads), windows per frame)`` of one compared configuration."""
    if kind == "fastdet":
        det = Detector() if stride == 16 else Detector(search=SearchConfig(cells_per_step=1))
        det.warmup()
        return (lambda frame, n: det.detect(frame)), sum(g.n_windows for g in det.geometries(FRAME_SHAPE))
    cv = OpenCVBands(stride)
    return cv.detect, cv.n_windows


def time_side_by_side(frames: dict[str, np.ndarray], thread_counts: list[int], calls: int,
                      rounds: int) -> tuple[dict, dict]:
    """Wall and CPU seconds per frame of every case of :data:`CASES` at every thread count,
    ``calls`` calls each over ``rounds`` interleaved rounds, cycling through ``frames``.
    Returns ``({(label, n): {"wall": [s...], "cpu": [s...]}}, {label: windows per frame})``."""
    runners, windows = {}, {}
    for label, kind, stride in CASES:
        runners[label], windows[label] = make_case(kind, stride)
    out = {(label, n): {"wall": [], "cpu": []} for label, _, _ in CASES for n in thread_counts}
    cycle = itertools.cycle(list(frames.values()))
    for label, _, _ in CASES:  # warm: caches, pools, first frame of this size
        for n in thread_counts:
            with threads(n):
                for f in frames.values():
                    runners[label](f, n)
    for _ in range(rounds):
        for label, _, _ in CASES:
            for n in thread_counts:
                with threads(n):
                    run = runners[label]
                    for _ in range(max(1, calls // rounds)):
                        f = next(cycle)
                        c0, t0 = time.process_time(), time.perf_counter()
                        run(f, n)
                        out[(label, n)]["wall"].append(time.perf_counter() - t0)
                        out[(label, n)]["cpu"].append(time.process_time() - c0)
    return out, windows


def summary(times: dict) -> dict:
    """``{(label, n): (best wall ms, median wall ms, median CPU ms)}``."""
    return {k: (1e3 * min(v["wall"]), 1e3 * statistics.median(v["wall"]), 1e3 * statistics.median(v["cpu"]))
            for k, v in times.items()}


# --------------------------------------------------------------------------------------
# benchmarks
# --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def frames(data):
    return load_frames(data)


@pytest.mark.parametrize("n_threads", [1, 2])
@pytest.mark.parametrize("case", CASES, ids=[c[0].replace(" ", "-") for c in CASES])
def test_side_by_side(benchmark, frames, case, n_threads):
    label, kind, stride = case
    run, n_windows = make_case(kind, stride)
    cycle = itertools.cycle(list(frames.values()))
    with threads(n_threads):
        for f in frames.values():
            run(f, n_threads)
        benchmark.group = GROUP
        benchmark.extra_info.update(case=label, threads=n_threads, windows_per_frame=n_windows,
                                    frame="test_images/*.jpg (cycled)", threading_layer=numba.threading_layer())
        benchmark(lambda: run(next(cycle), n_threads))

"""Detector speed on 1280x720 frames: the classic per-window pipeline vs fastdet, and the
Numba cold / warm start of ``Detector().detect``.

Run::

    python -m pytest benchmarks/bench_detector.py --benchmark-only
    python -m tools.studies.bench_report                 # the same figures as markdown tables

Frames: ``test_images/*.jpg`` (six 1280x720 dashcam frames). Model and search are the same
for both pipelines: the bundled main model (``fastdet.model.load_model()``) and the default
``fastdet.config.SearchConfig()`` (6 bands, 2 cells per step):

* ``classic``: ``tests.reference.ClassicDetector`` — skimage HOG of each scaled band,
  then every window one at a time (slice its blocks, ``cv2.resize`` spatial bins,
  ``np.histogram``, ``StandardScaler.transform``, ``decision_function``). About 5 s a
  frame, so 2 rounds on test1.jpg (``pedantic``);
* ``fastdet main``: ``Detector(oncoming=None).detect`` — the same model and bands, every
  window of a band scored at once by the Numba kernels; at 1 and 2 Numba threads;
* ``fastdet default``: ``Detector().detect`` — the detector alone, whose default has no
  oncoming-traffic model (``video`` adds the bundled one in ``VideoDetector``, where motion
  narrows its search), so today this is the same as ``fastdet main`` (a separate row so the
  figure stays right if the default changes; ``extra_info["models"]`` says which);
* ``fastdet main + oncoming``: ``Detector(oncoming=PATH)`` with the oncoming-traffic model in
  ``$FASTDET_BENCH_ONCOMING`` (one trained with ``python -m fastdet train --window-rows``) and
  its default search (``fastdet.config.ONCOMING_SEARCH``); skipped when the variable is unset.

fastdet cases cycle through the six frames, one frame per call. Both pipelines give the
same positive windows on test1.jpg (checked after the classic run). Like the ``video``
command, idle OpenMP workers sleep (``OMP_WAIT_POLICY=PASSIVE`` unless set): with GNU
OpenMP's default spinning, a 2-thread run on a machine where another job holds a core was
10x slower.

Start-up: a fresh interpreter imports fastdet, builds ``Detector()`` and calls ``detect``
on test1.jpg twice, with ``NUMBA_CACHE_DIR`` pointing at an empty folder (cold: every
kernel is compiled) and then again with that folder filled (warm: loaded from disk).
"""
from __future__ import annotations

import itertools
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before Numba's OpenMP layer starts

import cv2  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from benchmarks.bench_hog import threads  # noqa: E402
from fastdet.config import SearchConfig  # noqa: E402
from fastdet.data import data_dir  # noqa: E402
from fastdet.detect import Detector, DetectStats  # noqa: E402
from fastdet.model import load_model  # noqa: E402

GROUP = "Detector.detect, 1280x720 frame, default 6 bands"
REPO = Path(__file__).resolve().parent.parent
CLASSIC_FRAME = "test1.jpg"


# --------------------------------------------------------------------------------------
# helpers (also used by tools/studies/bench_report.py)
# --------------------------------------------------------------------------------------
def load_frames(data: Path | None = None) -> dict[str, np.ndarray]:
    """``{name: frame}`` for ``test_images/*.jpg`` (BGR uint8), sorted by name."""
    data = data_dir() if data is None else data
    paths = sorted((data / "test_images").glob("*.jpg"))
    if not paths:
        raise FileNotFoundError(f"no test_images/*.jpg in {data}")
    frames = {p.name: cv2.imread(str(p)) for p in paths}
    bad = [n for n, f in frames.items() if f is None]
    if bad:
        raise FileNotFoundError(f"unreadable: {bad}")
    return frames


def make_classic():
    """The classic pipeline with the bundled main model and the default search."""
    from tests.reference import ClassicDetector  # here: it imports scikit-image and scikit-learn

    return ClassicDetector(load_model(), SearchConfig())


def make_fastdet(kind: str, oncoming: str | os.PathLike | None = None):
    """``'main'``: ``Detector(oncoming=None)`` (same model and bands as the classic one);
    ``'default'``: ``Detector()``; ``'oncoming'``: ``Detector(oncoming=oncoming)``."""
    if kind == "main":
        det = Detector(oncoming=None)
    elif kind == "default":
        det = Detector()
    elif kind == "oncoming":
        if oncoming is None:
            raise ValueError("kind 'oncoming' needs an oncoming-traffic model")
        det = Detector(oncoming=oncoming)
    else:
        raise ValueError(f"unknown detector kind {kind!r}")
    det.warmup()
    return det


def models_label(det) -> str:
    return "main" if det.oncoming_model is None else "main + oncoming"


def time_detectors(dets: dict[str, Detector], frames: dict[str, np.ndarray], thread_counts: list[int],
                   calls: int, rounds: int) -> tuple[dict, dict]:
    """Seconds per ``detect`` of every detector at every thread count: ``calls`` calls each,
    cycling through ``frames``, in ``rounds`` interleaved rounds (so a burst of load from
    another program hits all of them alike), after a warm-up pass over the frames.
    Returns ``times {(kind, n): [s, ...]}`` and ``stages {(kind, n): {stage: [s, ...]}}``
    (the :class:`~fastdet.detect.DetectStats` timings of each call)."""
    configs = [(kind, n) for kind in dets for n in thread_counts]
    times: dict = {c: [] for c in configs}
    stages: dict = {c: {} for c in configs}
    cycle = itertools.cycle(list(frames.values()))
    for kind, n in configs:  # warm: thread pool, first frame of this size
        with threads(n):
            for f in frames.values():
                dets[kind].detect(f)
    for _ in range(rounds):
        for kind, n in configs:
            with threads(n):
                det = dets[kind]
                for _ in range(calls // rounds):
                    f = next(cycle)
                    stats = DetectStats()
                    t0 = time.perf_counter()
                    det.detect(f, stats=stats)
                    times[(kind, n)].append(time.perf_counter() - t0)
                    for k, v in stats.timings.items():
                        stages[(kind, n)].setdefault(k, []).append(v)
    return times, stages


def time_classic(frame: np.ndarray, rounds: int):
    """``(seconds per run, the windows)`` of the classic pipeline (:func:`make_classic`) on
    ``frame``, ``rounds`` runs at 1 thread."""
    classic = make_classic()
    times = []
    with threads(1):
        for _ in range(rounds):
            t0 = time.perf_counter()
            result = classic.detect(frame)
            times.append(time.perf_counter() - t0)
    return times, result


_TOTAL = re.compile(r"^total(?: \(wall\))?\s+([\d.]+)\s+([\d.]+)", re.M)


def wait_policy_times(bench_args: list[str], repeat: int) -> dict[str, list[tuple[float, float]]]:
    """``{policy: [(best ms, median ms) per run]}`` of ``python -m fastdet bench BENCH_ARGS``
    (its ``total`` row: detect + heat map) in fresh processes with ``OMP_WAIT_POLICY`` =
    ``PASSIVE`` and ``ACTIVE``, ``repeat`` times each, interleaved."""
    res: dict[str, list[tuple[float, float]]] = {}
    for _ in range(repeat):
        for policy in ("PASSIVE", "ACTIVE"):
            env = dict(os.environ, OMP_WAIT_POLICY=policy)
            env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
            out = subprocess.run([sys.executable, "-m", "fastdet", "bench", *bench_args], env=env, cwd=REPO,
                                 capture_output=True, text=True, check=True).stdout
            m = _TOTAL.search(out)
            if m is None:
                raise RuntimeError(f"no total row in the output of fastdet bench:\n{out}")
            res.setdefault(policy, []).append((float(m.group(1)), float(m.group(2))))
    return res


def same_windows(a, b) -> bool:
    """Same set of positive-window boxes."""
    return set(map(tuple, np.asarray(a.boxes).tolist())) == set(map(tuple, np.asarray(b.boxes).tolist()))


_START_SCRIPT = """
import sys, time, json
t0 = time.perf_counter()
import cv2, numpy as np
from fastdet.detect import Detector
t1 = time.perf_counter()
det = Detector()
t2 = time.perf_counter()
frame = cv2.imread(sys.argv[1])
t3 = time.perf_counter()
det.detect(frame)
t4 = time.perf_counter()
det.detect(frame)
t5 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "construct_s": t2 - t1, "first_detect_s": t4 - t3,
                  "second_detect_s": t5 - t4, "models": "main" if det.oncoming_model is None else "main + oncoming"}))
"""


def _start_run(frame_file: Path, cache_dir: Path, n_threads: int) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), NUMBA_NUM_THREADS=str(n_threads))
    env.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", _START_SCRIPT, str(frame_file)], env=env,
                         capture_output=True, text=True, check=True, cwd=REPO)
    wall = time.perf_counter() - t0
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result["process_s"] = wall
    return result


def start_up_times(frame_file: Path | None = None, n_threads: int = 2) -> dict:
    """A fresh process: import fastdet.detector (``import_s``), ``Detector()``
    (``construct_s``: load the models), first ``detect`` of test1.jpg (``first_detect_s``:
    compile or load every kernel, start the threads) and a second one (``second_detect_s``);
    ``process_s``: the whole process, interpreter start-up included. ``cold_*``: empty
    ``NUMBA_CACHE_DIR``; ``warm_*``: the same folder, filled by the cold run."""
    frame_file = frame_file or data_dir() / "test_images" / CLASSIC_FRAME
    with tempfile.TemporaryDirectory(prefix="fastdet-numba-") as tmp:
        cold = _start_run(frame_file, Path(tmp), n_threads)
        warm = _start_run(frame_file, Path(tmp), n_threads)
    result = {f"cold_{k}": v for k, v in cold.items()}
    result.update({f"warm_{k}": v for k, v in warm.items()})
    return result


# --------------------------------------------------------------------------------------
# benchmarks
# --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def frames(data):
    return load_frames(data)


def test_classic(benchmark, frames):
    pytest.importorskip("skimage")
    frame = frames[CLASSIC_FRAME]
    classic = make_classic()
    benchmark.group = GROUP
    benchmark.extra_info.update(pipeline="classic", models="main", threads=1, frame=CLASSIC_FRAME)
    result = benchmark.pedantic(classic.detect, args=(frame,), rounds=2, iterations=1)
    fast = make_fastdet("main").detect(frame)
    benchmark.extra_info["windows"] = len(result.boxes)
    assert same_windows(result, fast), "classic and fastdet disagree on the positive windows"


@pytest.mark.parametrize("kind", ["main", "default", "oncoming"])
@pytest.mark.parametrize("n_threads", [1, 2])
def test_fastdet(benchmark, frames, kind, n_threads):
    oncoming = os.environ.get("FASTDET_BENCH_ONCOMING") or None
    if kind == "oncoming" and oncoming is None:
        pytest.skip("set FASTDET_BENCH_ONCOMING=MODEL.npz (a model trained with --window-rows) to time it")
    det = make_fastdet(kind, oncoming)
    cycle = itertools.cycle(list(frames.values()))
    with threads(n_threads):
        for f in frames.values():  # first frame of this size, caches, thread pool
            det.detect(f)
        benchmark.group = GROUP
        benchmark.extra_info.update(pipeline=f"fastdet {kind}", models=models_label(det), threads=n_threads,
                                    bands=sum(len(det.geometries((720, 1280), part))
                                              for part in range(1 + (det.oncoming_model is not None))),
                                    frame="test_images/*.jpg (cycled)",
                                    omp_wait_policy=os.environ.get("OMP_WAIT_POLICY"),
                                    threading_layer=numba.threading_layer())
        benchmark(lambda: det.detect(next(cycle)))
        stats = DetectStats()  # the stages of one more frame
        det.detect(next(cycle), stats=stats)
        benchmark.extra_info["timings_ms"] = {k: round(v * 1e3, 3) for k, v in stats.timings.items()}


def test_numba_start_up(benchmark):
    """Cold (empty NUMBA_CACHE_DIR) and warm start of a fresh process running
    ``Detector().detect``; the timing is both runs together, the split is in extra_info."""
    benchmark.group = "Detector Numba start-up (fresh process)"
    result = benchmark.pedantic(start_up_times, rounds=1, iterations=1)
    benchmark.extra_info.update({k: (round(v, 4) if isinstance(v, float) else v) for k, v in result.items()})
    print("\nDetector start-up:", ", ".join(f"{k}={v:.3f}s" for k, v in result.items() if isinstance(v, float)))
    assert result["warm_first_detect_s"] < result["cold_first_detect_s"]

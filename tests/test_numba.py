"""The kernels compile ahead of time, exactly for the calls the package makes
(:mod:`fastdet._numba`): every kernel module lists the signatures of its kernels; after the
warm-up the frame loop compiles nothing (at one and two threads); on a cold cache
``fastdet warmup`` (worker processes) compiles exactly what a run then needs; the compile
estimate's schedule; :func:`~fastdet._numba.split_range` covers a range once."""
from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import cv2
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba.core import event

import fastdet
from fastdet import _numba
from fastdet.features import _hog
from fastdet.features import _hog_kernels as _k

ROOT = Path(fastdet.__file__).resolve().parent


def test_every_kernel_module_lists_its_kernels_and_none_is_parallel():
    found = {".".join(p.relative_to(ROOT.parent).with_suffix("").parts) for p in ROOT.rglob("_*_kernels.py")}
    assert found == set(_numba.KERNEL_MODULES)
    for name in _numba.KERNEL_MODULES:
        mod = importlib.import_module(name)
        kernels = {k: v for k, v in vars(mod).items() if isinstance(v, numba.core.registry.CPUDispatcher)}
        public = {k for k in kernels if not k.startswith("_")}
        assert public == set(mod.SIGNATURES), name  # every kernel Python calls, and only those
        assert set(mod.COMPILE_SECONDS) == public, name
        for k, d in kernels.items():
            assert not d.targetoptions.get("parallel"), f"{name}.{k} is a parallel=True kernel"
            assert type(d._cache).__name__ == "FunctionCache", f"{name}.{k} is not cached on disk"
    for t in _numba.tasks_of(_numba.all_kernels()):
        assert all(isinstance(a, numba.core.types.Type) for a in t.signature()), t


class _Compiles(event.Listener):
    def __init__(self):
        self.seen: list[str] = []
        self.lock = threading.Lock()

    def on_start(self, ev):
        d = ev.data["dispatcher"]
        with self.lock:
            self.seen.append(f"{d.py_func.__module__}.{d.py_func.__name__}{ev.data['args']}")

    def on_end(self, ev):
        pass


@pytest.mark.parametrize("threads", [1, 2])
def test_the_frame_loop_compiles_nothing_after_the_warm_up(data, threads):
    """The quick-start pipeline (default VideoDetector: refinement, motion gate, tracker,
    guided search) on real frames: after ``warmup()`` no kernel meets a new signature."""
    cap = cv2.VideoCapture(str(data / "videos" / "test_video.mp4"))
    frames = []
    while len(frames) < 12:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    assert len(frames) == 12
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        vd = fastdet.VideoDetector()
        vd.warmup()
        listener = _Compiles()
        with event.install_listener("numba:compile", listener):
            boxes = [vd.update(f) for f in frames]
            fastdet.hog_channels(frames[0][400:600], exact=False)  # a band big enough to split over threads
    finally:
        numba.set_num_threads(before)
    assert listener.seen == []
    assert sum(len(b) for b in boxes) > 0  # the frames did reach the kernels


def test_schedule_puts_the_longest_first_on_the_least_loaded():
    costs = {"a": 8.0, "b": 4.0, "c": 3.0, "d": 2.0, "e": 1.0}
    plan = _numba._schedule(costs, 2)
    assert sorted(sum(plan, [])) == sorted(costs)
    assert plan[0][0] == "a" and plan[1][0] == "b"
    loads = [sum(costs[k] for k in p) for p in plan]
    assert max(loads) == 9.0
    # a worker that starts late gets less
    late = _numba._schedule(costs, 2, start=5.0)
    assert sum(costs[k] for k in late[0]) > sum(costs[k] for k in late[1])


def test_estimate_uses_this_machines_record(tmp_path, monkeypatch):
    tasks = _numba.tasks_of([_k.cell_hists_u8, _k.normalize_blocks_fast])
    rec = tmp_path / "times.json"
    rec.write_text('{"%s": 7.0, "%s": 3.0}' % (tasks[0].key, tasks[1].key))
    monkeypatch.setattr(_numba, "_times_path", lambda t: rec)
    monkeypatch.setattr(_numba, "machine_probe", lambda: (1.0, 1.0))
    monkeypatch.setattr(_numba, "_cores", lambda: 2)
    est = _numba.estimate(tasks, workers=2)
    assert est.measured and est.costs == {tasks[0].key: 7.0, tasks[1].key: 3.0}
    # 7 s here; 3 s in a worker after its start-up; then loading the code
    init = _numba.COMPILER_INIT_SECONDS
    alone = max(init + 7.0, init + 3.0 + _numba.WORKER_START_SECONDS) + 2 * _numba.LOAD_SECONDS
    assert est.seconds == pytest.approx(alone)
    # a busy machine: the probe got half a core, i.e. 3 others want the 2 cores; with our 2
    # processes each gets 2 / 5 of a core
    monkeypatch.setattr(_numba, "machine_probe", lambda: (1.0, 0.5))
    assert _numba.estimate(tasks, workers=2).seconds == pytest.approx(alone / 0.4)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 200), st.integers(1, 8))
def test_split_range_covers_every_index_once(n, parts):
    hits = np.zeros(n, np.int64)
    lock = threading.Lock()

    def fn(lo, hi):
        with lock:
            hits[lo:hi] += 1

    _numba.split_range(fn, n, parts)
    assert (hits == 1).all()


def test_split_range_reraises():
    def fn(lo, hi):
        if lo > 0:
            raise ValueError("boom")

    with pytest.raises(ValueError, match="boom"):
        _numba.split_range(fn, 10, 2)


# --------------------------------------------------------------------------------------
# the merged kernels: ranges of rows give the whole, bit for bit
# --------------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(st.integers(1, 9), st.integers(1, 9), st.integers(1, 3), st.integers(1, 3), st.sampled_from([0, 1, 2, 3]),
       st.integers(1, 12), st.integers(0, 2**32 - 1))
def test_block_rows_in_ranges_equal_the_whole(rows, cols, n_ch, cpb, method, orientations, seed):
    """Both normalisations (exact and fast), block rows cut anywhere: the same bits."""
    rng = np.random.default_rng(seed)
    ht = rng.random((rows + cpb - 1, n_ch, cols + cpb - 1, orientations))
    ht[rng.random(ht.shape) < 0.3] = 0.0
    for kernel in (_k.normalize_blocks, _k.normalize_blocks_fast):
        whole = np.empty((rows, cols, n_ch, cpb * cpb * orientations))
        kernel(ht, 0, rows, cpb, cpb, method, whole)
        cut = int(rng.integers(0, rows + 1))
        parts = np.full_like(whole, np.nan)
        kernel(ht, 0, cut, cpb, cpb, method, parts)
        kernel(ht, cut, rows, cpb, cpb, method, parts)
        np.testing.assert_array_equal(parts, whole)


@pytest.mark.parametrize("threads", [1, 2])
def test_batch_equals_one_image_at_a_time_at_one_and_two_threads(threads):
    imgs = np.random.default_rng(threads).integers(0, 256, (9, 64, 64, 3), dtype=np.uint8)
    batch = _hog.hog_channels_batch(imgs, 9, 8, 2, threads=threads)
    for i in range(len(imgs)):
        np.testing.assert_array_equal(batch[i], _hog.hog_channels(imgs[i], 9, 8, 2))


@pytest.mark.parametrize("exact", [True, False])
def test_a_band_split_over_threads_equals_one_thread(test_images, exact):
    img = cv2.cvtColor(cv2.imread(str(test_images[0])), cv2.COLOR_BGR2YCrCb)[380:640]
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = fastdet.hog_channels(img, 16, 8, 2, exact=exact)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = fastdet.hog_channels(img, 16, 8, 2, exact=exact)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one, many)


# --------------------------------------------------------------------------------------
# a cold cache: `fastdet warmup` in worker processes, then a run compiles nothing
# --------------------------------------------------------------------------------------
@pytest.mark.slow
def test_warmup_compiles_what_a_run_needs(tmp_path):
    from tests.media import write_video

    clip = write_video(tmp_path / "c.mp4", 5)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), _numba.WORKERS_ENV: "2"}
    env.pop("PYTHONPATH", None)
    r = subprocess.run([sys.executable, "-m", "fastdet", "warmup"], capture_output=True, text=True, env=env,
                       timeout=900, check=False, cwd=ROOT.parent)
    assert r.returncode == 0, r.stderr
    m = re.search(r"compiling every kernel \(first run only: (\d+) kernels on 2 cores, about (\d+) s", r.stderr)
    assert m, r.stderr
    assert re.search(r"compiled every kernel in [\d.]+ s \(estimated \d+ s\)", r.stderr), r.stderr
    assert list((tmp_path / "cache").rglob(_numba._TIMES_FILE))  # this machine's figures, for the next estimate
    # everything is there now: a second warm-up compiles nothing, a run neither (in this process or later)
    r = subprocess.run([sys.executable, "-m", "fastdet", "warmup"], capture_output=True, text=True, env=env,
                       timeout=300, check=False, cwd=ROOT.parent)
    assert r.returncode == 0 and "already compiled" in r.stderr, r.stderr
    r = subprocess.run([sys.executable, "tools/studies/compile_profile.py", "--cache", str(tmp_path / "cache"), "--",
                        "video", str(clip), "--boxes", str(tmp_path / "b.txt"), "--no-progress"],
                       capture_output=True, text=True, env=env, timeout=300, check=False, cwd=ROOT.parent)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "warm-up: 0 signatures compiled" in r.stdout and "later: 0 signatures compiled" in r.stdout, r.stdout
    assert "compiling" not in r.stderr, r.stderr

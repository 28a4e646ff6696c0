"""The kernels compile ahead of time, exactly for the calls the package makes, and the first
run speaks (:mod:`fastdet._numba`).

- Every kernel module lists the signatures of its kernels; after the warm-up the frame loop
  compiles nothing (at one and two threads); on a cold cache ``fastdet warmup`` (worker
  processes) compiles exactly what a run then needs; the compile estimate's schedule;
  :func:`~fastdet._numba.split_range` covers a range once; merged kernels give the same bits
  in ranges as whole.
- One notice before the kernels compile, the whole wall time beside the fps, and a Numba
  cache that stays valid when the package is installed where it cannot write (Numba then
  falls back to a user cache folder). The read-only install is a real read-only bind mount of
  a copy of the package, made in a user + mount namespace (``unshare -rm``): as root, file
  permissions alone would not stop writes. Cold compiles: marked slow; the warm-up test and the
  read-only test share one (a module fixture: ``fastdet warmup`` on an empty cache, in the
  read-only install, then each test's later runs).
"""
from __future__ import annotations

import importlib
import os
import re
import shutil
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
from fastdet._numba import compile_time
from fastdet.features import _hog
from fastdet.features import _hog_kernels as _k
from tests.media import frames

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
    monkeypatch.setattr(compile_time, "_times_path", lambda t: rec)
    monkeypatch.setattr(compile_time, "machine_probe", lambda: (1.0, 1.0))
    monkeypatch.setattr(compile_time, "_cores", lambda: 2)
    est = _numba.estimate(tasks, workers=2)
    assert est.measured and est.costs == {tasks[0].key: 7.0, tasks[1].key: 3.0}
    # 7 s here; 3 s in a worker after its start-up; then loading the code
    init = _numba.COMPILER_INIT_SECONDS
    alone = max(init + 7.0, init + 3.0 + _numba.WORKER_START_SECONDS) + 2 * _numba.LOAD_SECONDS
    assert est.seconds == pytest.approx(alone)
    # a busy machine: the probe got half a core, i.e. 3 others want the 2 cores; with our 2
    # processes each gets 2 / 5 of a core
    monkeypatch.setattr(compile_time, "machine_probe", lambda: (1.0, 0.5))
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


def test_serial_kernels_is_one_thread_in_the_block_only_and_in_this_thread_only():
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs two Numba threads")
    before = numba.get_num_threads()
    seen = []
    with pytest.raises(RuntimeError):
        with _numba.serial_kernels():
            seen.append(numba.get_num_threads())
            other = threading.Thread(target=lambda: seen.append(numba.get_num_threads()))
            other.start()
            other.join()
            raise RuntimeError("the setting comes back on an error too")
    assert seen == [1, numba.config.NUMBA_NUM_THREADS]
    assert numba.get_num_threads() == before


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
# a cold cache: `fastdet warmup` in worker processes, then a run compiles nothing; in a
# read-only install the kernels go to the user cache folder
# --------------------------------------------------------------------------------------
def _unshare_works() -> bool:
    if shutil.which("unshare") is None:
        return False
    r = subprocess.run(["unshare", "-rm", "true"], capture_output=True, check=False)
    return r.returncode == 0


_READ_ONLY = _unshare_works()


@pytest.fixture(scope="module")
def cold_cache(tmp_path_factory) -> dict:
    """ONE cold compile for the two tests below (it is most of each one's time): ``fastdet
    warmup`` on an empty cache in 2 worker processes, then the runs each test checks, every
    step's stdout, stderr and status kept apart (``steps[name]``).

    Where a user + mount namespace can be made (``unshare -rm``), all of it runs on a copy of
    the package under a real read-only bind mount (as root, file permissions alone would not
    stop writes), with ``NUMBA_CACHE_DIR`` unset: Numba must fall back to the user cache folder
    (``XDG_CACHE_HOME``). Elsewhere on this checkout with ``NUMBA_CACHE_DIR`` set to that same
    folder (and the read-only test is skipped)."""
    from tests.media import write_video

    tmp = tmp_path_factory.mktemp("cold")
    clip = write_video(tmp / "c.mp4", 5)
    img = tmp / "in.jpg"
    cv2.imwrite(str(img), next(frames(1, 640, 360)))
    cache, steps_dir = tmp / "cache", tmp / "steps"
    steps_dir.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update({_numba.WORKERS_ENV: "2", "XDG_CACHE_HOME": str(cache)})
    if _READ_ONLY:
        site = tmp / "site"
        shutil.copytree(ROOT, site / "fastdet", copy_function=shutil.copy2,
                        ignore=shutil.ignore_patterns("__pycache__"))
        mount = (f"mount --bind {site} {site} && mount -o remount,bind,ro {site} {site} && "
                 f"touch {site}/fastdet/probe 2>/dev/null && echo WRITABLE > {steps_dir}/mount.out; ")
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    else:
        site = ROOT.parent
        mount = ""
        env["NUMBA_CACHE_DIR"] = str(cache / "numba")  # where the user cache folder would hold them
    # run the copy, not the checkout an editable install points at (its finder comes first)
    launcher = tmp / "launch.py"
    launcher.write_text(
        "import runpy, sys\n"
        "sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in getattr(f, '__module__', '')]\n"
        "import fastdet\n"
        f"assert fastdet.__file__.startswith({str(site)!r}), fastdet.__file__\n"
        "sys.argv[0] = 'fastdet'\n"
        "runpy.run_module('fastdet', run_name='__main__')\n")
    fastdet_cmd = f"PYTHONPATH={site} {sys.executable} {launcher}"
    commands = {
        "warmup1": f"{fastdet_cmd} warmup",  # the cold compile
        "warmup2": f"{fastdet_cmd} warmup",
        # a later run (one is enough: it loads the kernels the warm-up stored, or says it compiles)
        "image": f"{fastdet_cmd} image {img} -o {tmp}/out.jpg",
        # the profile imports fastdet from its working folder: the copy
        "profile": (f"cd {site} && PYTHONPATH={site} {sys.executable} {ROOT.parent}/tools/studies/compile_profile.py "
                    f"--cache {cache}/numba -- video {clip} --boxes {tmp}/b.txt --no-progress"),
    }
    script = mount + "; ".join(f"({c}) > {steps_dir}/{n}.out 2> {steps_dir}/{n}.err; echo $? > {steps_dir}/{n}.rc"
                               for n, c in commands.items())
    cmd = ["unshare", "-rm", "sh", "-c", script] if _READ_ONLY else ["sh", "-c", script]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, env=env, check=False, cwd=tmp)
    assert r.returncode == 0, r.stdout + r.stderr

    def step(name: str) -> subprocess.CompletedProcess:
        rc = steps_dir / f"{name}.rc"
        return subprocess.CompletedProcess(commands[name], int(rc.read_text()) if rc.exists() else -1,
                                           (steps_dir / f"{name}.out").read_text(),
                                           (steps_dir / f"{name}.err").read_text())

    return dict(steps={n: step(n) for n in commands}, tmp=tmp, cache=cache, site=site,
                writable=(steps_dir / "mount.out").exists())


@pytest.mark.slow
def test_warmup_compiles_what_a_run_needs(cold_cache):
    steps, cache = cold_cache["steps"], cold_cache["cache"]
    r = steps["warmup1"]
    assert r.returncode == 0, r.stderr
    m = re.search(r"compiling every kernel \(first run only: (\d+) kernels on 2 cores, about (\d+) s", r.stderr)
    assert m, r.stderr
    assert re.search(r"compiled every kernel in [\d.]+ s \(estimated \d+ s\)", r.stderr), r.stderr
    assert list(cache.rglob(_numba._TIMES_FILE))  # this machine's figures, for the next estimate
    # everything is there now: a second warm-up compiles nothing, a run neither (in this process or later)
    r = steps["warmup2"]
    assert r.returncode == 0 and "already compiled" in r.stderr, r.stderr
    r = steps["profile"]
    assert r.returncode == 0, r.stdout + r.stderr
    assert "warm-up: 0 signatures compiled" in r.stdout and "later: 0 signatures compiled" in r.stdout, r.stdout
    assert "compiling" not in r.stderr, r.stderr


@pytest.mark.slow
@pytest.mark.skipif(not _READ_ONLY, reason="needs user + mount namespaces (unshare -rm) for a read-only mount")
def test_read_only_install_caches_in_the_user_folder(cold_cache):
    steps, cache, site, tmp = (cold_cache[k] for k in ("steps", "cache", "site", "tmp"))
    assert not cold_cache["writable"], "the mount is not read-only"
    assert [steps[n].returncode for n in ("warmup1", "image")] == [0, 0], \
        "".join(steps[n].stderr for n in ("warmup1", "image"))
    # first run: one notice, then the kernels land in the user cache folder ...
    err = steps["warmup1"].stderr
    assert err.count("compiling every kernel") == 1, err
    assert err.splitlines()[0].startswith("fastdet warmup: compiling"), err
    assert list(cache.rglob("*.nbi")) and list(cache.rglob("*.nbc"))
    assert not list((site / "fastdet").rglob("*.nbi"))
    # ... and a later run loads them: no notice (it is printed only for kernels not cached)
    assert "compiling" not in steps["image"].stderr, steps["image"].stderr
    assert (tmp / "out.jpg").exists()


def test_summary_reports_the_whole_wall_time(tmp_path):
    """``video`` prints the frame loop's fps and the whole run's wall time (start-up,
    loading and on a first run compiling included), which is the larger."""
    from tests.media import write_video

    clip = write_video(tmp_path / "c.mp4", 5)
    r = subprocess.run([sys.executable, "-m", "fastdet", "video", str(clip), "--boxes", str(tmp_path / "b.txt"),
                        "--no-progress"], capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    m = re.search(r"5 frames in ([\d.]+) s, [\d.]+ fps \(([\d.]+) s in all, start-up included\)", r.stdout)
    assert m, r.stdout
    assert float(m.group(2)) >= float(m.group(1))


#: a child process whose Numba cache saves fail as on a full disk: one cached function compiled
_FULL_CACHE = """\
import errno, sys
from numba.core import caching
import fastdet._numba  # noqa: F401  (what every kernel module imports first)
def full(self, *args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")
caching.IndexDataCacheFile.save = full
import cached_mod
print(cached_mod.add_one(2), cached_mod.add_one(3.5))
print(fastdet._numba.cache_failed())
"""


def test_a_cache_that_cannot_be_written_is_one_note_and_the_run_goes_on(tmp_path):
    """A full disk (or a read-only folder) under the Numba cache: before, Numba's ``OSError: [Errno
    28] No space left on device`` traceback ended ``warmup`` and a first ``video`` run (issue 34,
    item 13); now one note, once, and the compiled code is used from memory."""
    (tmp_path / "cached_mod.py").write_text("import numba\n\n@numba.njit(cache=True)\ndef add_one(x):\n"
                                            "    return x + 1\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT.parent)])}
    p = subprocess.run([sys.executable, "-c", _FULL_CACHE], capture_output=True, text=True, env=env, timeout=300,
                       cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split("\n")[:2] == ["3 4.5", "No space left on device"], p.stdout
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot write the compiled kernels to the Numba cache" in lines[0], p.stderr
    assert "No space left on device" in lines[0] and "Traceback" not in p.stderr


def test_a_cache_error_that_is_not_the_places_still_shows(tmp_path, monkeypatch):
    """Only errors of the place written to are tolerated: anything else is Numba's (a bug)."""
    import errno

    from numba.core import caching

    from fastdet._numba import cache

    calls = []

    def broken(self, sig, data):
        calls.append(sig)
        raise OSError(errno.EBADF, "Bad file descriptor")

    monkeypatch.setattr(caching.Cache, "save_overload", broken)
    cache.tolerate_cache_writes()
    with pytest.raises(OSError, match="Bad file descriptor"):
        caching.Cache.save_overload(object(), "sig", None)
    assert calls == ["sig"]


def test_no_writable_cache_folder_anywhere_is_one_note(tmp_path):
    """A read-only container (``NUMBA_CACHE_DIR`` read-only, the package read-only, no writable
    user cache folder): Numba raised ``RuntimeError: cannot cache function ...: no locator
    available`` when a kernel module was imported; now one note and the code compiles in memory."""
    (tmp_path / "cached_mod.py").write_text("import numba\n\n@numba.njit(cache=True)\ndef add_one(x):\n"
                                            "    return x + 1\n")
    code = ("from numba.core import caching\n"
            "import fastdet._numba\n"
            "caching.CacheImpl._locator_classes = []  # no folder Numba could write\n"
            "import cached_mod\n"
            "print(cached_mod.add_one(2), fastdet._numba.cache_failed())\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(ROOT.parent)])}
    env.pop("NUMBA_CACHE_DIR", None)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "3 no folder can be written", p.stdout
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "no folder for the Numba cache can be written" in lines[0], p.stderr

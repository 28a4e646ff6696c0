"""Numba compile options, ahead-of-time compilation of the kernels, and the thread helper.

``EXACT``: IEEE arithmetic in source order (what the kernels compared bit-for-bit or to
1e-12 against scikit-image and NumPy use). ``REASSOC``: lets LLVM reassociate sums and fuse
multiply-adds so dot products vectorise (the scoring kernels, checked to 1e-6 against the
classic per-window pipeline). Every kernel caches its machine code on disk (``cache=True``:
compile cost is paid once per install; Numba falls back to a user cache folder when the
package folder is read-only) and releases the GIL (``nogil=True``) so band threads, the
reader and the writer overlap. No kernel is ``parallel=True`` (parfors compile several times
slower): :func:`split_range` spreads a kernel's rows over threads instead.

Every kernel module (:data:`KERNEL_MODULES`) lists in ``SIGNATURES`` the argument types the
package calls each of its kernels with -- exactly those of the calls, so that a call finds
its machine code and never compiles a second specialisation -- and in ``COMPILE_SECONDS``
what compiling each costs on one core of the reference machine (``docs/benchmarks.md``).
:func:`ensure_compiled` compiles what the on-disk cache lacks before a run starts: in worker
processes, one per core (Numba's compiler holds a global lock, so threads would take turns),
which fill the same cache; then this process loads the machine code. It says so first, with
an estimate (the kernels still to compile x their cost on this machine: measured by earlier
compiles here, else the reference figure scaled by a quick speed probe), and shows the
progress on a terminal. ``python -m fastdet warmup`` compiles every kernel ahead of time.
"""
from __future__ import annotations

import importlib
import json
import os
import queue
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numba

from . import console

EXACT: dict[str, Any] = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
REASSOC: dict[str, Any] = dict(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")

#: every module of numba kernels (each with ``SIGNATURES`` and ``COMPILE_SECONDS``)
KERNEL_MODULES = (
    "fastdet.features._hog_kernels",
    "fastdet.features._window_kernels",
    "fastdet.detect._score_kernels",
    "fastdet.video._heat_kernels",
    "fastdet.video._label_kernels",
    "fastdet.video._motion_kernels",
)

#: CPU seconds of one unit of the speed probe (:func:`machine_probe`) on the reference machine
PROBE_UNIT_SECONDS = 0.0013
#: CPU seconds of a worker process's start (Python, NumPy, Numba, the kernel modules), reference machine
WORKER_START_SECONDS = 1.0
#: CPU seconds of the first compile in a process (Numba sets up its typing and LLVM), reference machine
COMPILER_INIT_SECONDS = 0.8
#: CPU seconds to load one kernel signature's machine code from the cache, reference machine
LOAD_SECONDS = 0.05
#: environment variable: the number of compile worker processes (0 or 1: compile in this process)
WORKERS_ENV = "FASTDET_COMPILE_WORKERS"
_TIMES_FILE = "fastdet-compile-seconds.json"


# --------------------------------------------------------------------------------------
# the kernels and their signatures
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Task:
    """One signature of one kernel: ``module:function:index`` into its ``SIGNATURES`` list."""

    module: str
    name: str
    index: int

    @property
    def key(self) -> str:
        return f"{self.module}:{self.name}:{self.index}"

    @classmethod
    def parse(cls, key: str) -> Task:
        module, name, index = key.rsplit(":", 2)
        return cls(module, name, int(index))

    def dispatcher(self) -> Any:
        return getattr(importlib.import_module(self.module), self.name)

    def signature(self) -> tuple:
        """The argument types, as the tuple a call's dispatch compiles (and caches) under."""
        text = importlib.import_module(self.module).SIGNATURES[self.name][self.index]
        args, _ = numba.core.sigutils.normalize_signature(f"({text},)")
        return tuple(args)

    def reference_seconds(self) -> float:
        """Compile seconds on one core of the reference machine (the kernel's figure shared
        among its signatures)."""
        mod = importlib.import_module(self.module)
        return float(mod.COMPILE_SECONDS.get(self.name, 2.0)) / len(mod.SIGNATURES[self.name])


def tasks_of(kernels: Iterable[Any]) -> list[Task]:
    """Every listed signature of ``kernels`` (Numba dispatchers of the kernel modules)."""
    out = []
    for d in kernels:
        module, name = d.py_func.__module__, d.py_func.__name__
        sigs = importlib.import_module(module).SIGNATURES[name]
        out += [Task(module, name, i) for i in range(len(sigs))]
    return out


def all_kernels() -> list[Any]:
    """The dispatchers of every kernel the package calls (every ``SIGNATURES`` entry)."""
    out = []
    for m in KERNEL_MODULES:
        mod = importlib.import_module(m)
        out += [getattr(mod, name) for name in mod.SIGNATURES]
    return out


def is_cached(task: Task) -> bool:
    """``task``'s machine code is loaded in this process or in the on-disk cache (looked up
    where Numba will look; a stale entry of an edited source does not count)."""
    d = task.dispatcher()
    sig = task.signature()
    if sig in d.overloads:
        return True
    try:
        key = d._cache._index_key(sig, d.targetctx.codegen())
        return key in d._cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - Numba internals changed: compile (a cached kernel then just loads)
        return False


# --------------------------------------------------------------------------------------
# the estimate
# --------------------------------------------------------------------------------------
def _probe_unit() -> None:
    acc: dict[int, list[int]] = {}
    for i in range(3000):
        acc.setdefault(i % 97, []).append(i * 7 % 13)
    sorted(str(v) for v in acc.values())


def machine_probe(seconds: float = 0.25) -> tuple[float, float]:
    """``(speed, share)`` of this machine now, from ``seconds`` of pure-Python work
    (compiling is mostly Python and LLVM on one core): ``speed`` is its CPU seconds against
    the reference machine's (:data:`PROBE_UNIT_SECONDS` per unit; 2 = half as fast), ``share``
    the fraction of the wall time it got a core (below 1 on a machine busy with others)."""
    t0, c0 = time.perf_counter(), time.thread_time()
    units = 0
    while units < 3 or time.perf_counter() - t0 < seconds:
        _probe_unit()
        units += 1
    wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
    return max(cpu / units / PROBE_UNIT_SECONDS, 0.25), min(1.0, cpu / wall) if wall > 0 else 1.0


def _times_path(tasks: Sequence[Task]) -> Path | None:
    """Where this machine's measured compile seconds are kept: beside the kernels' cache."""
    try:
        return Path(tasks[0].dispatcher()._cache._cache_path) / _TIMES_FILE
    except Exception:  # noqa: BLE001 - no cache folder known: no record
        return None


def _load_times(path: Path | None) -> dict[str, float]:
    if path is None:
        return {}
    try:
        data = json.loads(path.read_text())
        return {str(k): float(v) for k, v in data.items()} if isinstance(data, dict) else {}
    except (OSError, ValueError, TypeError):
        return {}


def _save_times(path: Path | None, times: dict[str, float]) -> None:
    if path is None or not times:
        return
    merged = {**_load_times(path), **{k: round(v, 3) for k, v in times.items()}}
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(merged, indent=0, sort_keys=True))
        os.replace(tmp, path)
    except OSError:  # a record we could not keep: the next estimate uses the probe again
        try:
            tmp.unlink()
        except OSError:
            pass


def _schedule(costs: dict[str, float], workers: int, start: float = 0.0) -> list[list[str]]:
    """Longest first, each to the least loaded worker (all but the first start ``start``
    seconds late): the tasks of each worker."""
    loads = [0.0] + [start] * (workers - 1)
    plan: list[list[str]] = [[] for _ in range(workers)]
    for key in sorted(costs, key=lambda k: -costs[k]):
        w = loads.index(min(loads))
        plan[w].append(key)
        loads[w] += costs[key]
    return [p for p in plan if p]


@dataclass
class Estimate:
    """What compiling some tasks should take here: per task CPU seconds, the processes
    (this one and workers) and their shares, and the wall seconds in all."""

    costs: dict[str, float]
    workers: int
    seconds: float
    measured: bool  # every cost from an earlier compile on this machine
    plan: list[list[str]] = field(default_factory=list)


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _workers(n_tasks: int) -> int:
    env = os.environ.get(WORKERS_ENV, "").strip()
    if env:
        try:
            return max(1, min(int(env), n_tasks))
        except ValueError:
            pass
    return max(1, min(_cores(), n_tasks))


def estimate(tasks: Sequence[Task], workers: int | None = None) -> Estimate:
    """The compile time of ``tasks`` on this machine now: each task's CPU seconds (measured
    by an earlier compile here, else the reference figure x this machine's speed), shared
    out longest first among ``workers`` processes (default: one per core), each process's
    sum divided by the share of a core it can expect (from how busy the machine is), plus
    the workers' start-up and the loading of the code."""
    known = _load_times(_times_path(tasks)) if tasks else {}
    speed, share = machine_probe()
    costs = {t.key: known[t.key] if t.key in known else t.reference_seconds() * speed for t in tasks}
    w = workers or _workers(len(tasks))
    cores = _cores()
    # others: the runnable processes besides the probe that its share implies
    others = cores / share - 1 if share < 0.9 else 0.0
    init, start = COMPILER_INIT_SECONDS * speed, WORKER_START_SECONDS * speed
    plan = _schedule(costs, w, start)
    per_process = min(1.0, cores / max(others + len(plan), 1e-9))
    longest = max((init + sum(costs[k] for k in p) + (start if i else 0.0) for i, p in enumerate(plan)), default=0.0)
    seconds = (longest + LOAD_SECONDS * speed * len(tasks)) / per_process
    return Estimate(costs, len(plan) or 1, seconds, len(known) > 0 and all(t.key in known for t in tasks), plan)


# --------------------------------------------------------------------------------------
# compiling
# --------------------------------------------------------------------------------------
_compile_lock = threading.Lock()


def ensure_compiled(kernels: Iterable[Any], what: str = "the detection kernels", *,
                    always_report: bool = False) -> dict[str, Any]:
    """Make every listed signature of ``kernels`` ready in this process: load what the cache
    has; compile the rest first (worker processes when more than one core and task), after
    one note saying what and how long. Returns a report: ``compiled`` (tasks), ``estimate``
    and ``seconds`` (wall, 0 when nothing compiled), ``workers``.

    ``always_report``: also print a line when everything was cached (``fastdet warmup``)."""
    tasks = tasks_of(kernels)
    with _compile_lock:
        missing = [t for t in tasks if not is_cached(t)]
        report: dict[str, Any] = dict(compiled=len(missing), kernels=len(tasks), estimate=0.0, seconds=0.0,
                                      workers=0)
        if missing:
            est = estimate(missing)
            report.update(estimate=est.seconds, workers=est.workers)
            n_fn = len({(t.module, t.name) for t in missing})
            cores = f" on {est.workers} cores" if est.workers > 1 else ""
            console.note(f"compiling {what} (first run only: {n_fn} kernels{cores}, about {est.seconds:.0f} s; "
                         f"later runs load them from the cache)", once="compile")
            t0 = time.perf_counter()
            times = _compile(missing, est)
            report["seconds"] = time.perf_counter() - t0
            _save_times(_times_path(missing), times)
        for t in tasks:  # load (or, when a worker failed, compile here: its error shows)
            t.dispatcher().compile(t.signature())
        if missing:
            report["seconds"] = time.perf_counter() - t0
            console.status(f"compiled {what} in {report['seconds']:.1f} s (estimated {report['estimate']:.0f} s)",
                           final=True)
        elif always_report:
            console.note(f"{what}: all {len(tasks)} kernel signatures already compiled (in the cache)")
    return report


def _compile(missing: list[Task], est: Estimate) -> dict[str, float]:
    """Compile ``missing`` (into the on-disk cache), showing progress; the measured CPU
    seconds of each task."""
    total = len(missing)
    t0 = time.perf_counter()

    def show(done: int) -> None:
        el = time.perf_counter() - t0
        console.status(f"compiling: {done}/{total} kernel signatures, {el:.0f} s of about {est.seconds:.0f} s")

    times: dict[str, float] = {}
    if est.workers <= 1:
        show(0)
        _init_compiler()
        for i, t in enumerate(missing):
            c1 = time.thread_time()
            t.dispatcher().compile(t.signature())
            times[t.key] = time.thread_time() - c1
            show(i + 1)
        return times
    done: queue.Queue = queue.Queue()
    procs = []
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parent.parent)
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env[WORKERS_ENV] = "1"
    try:
        # the first share here (its code is then loaded already), the others in worker processes
        for plan in est.plan[1:]:
            try:
                p = subprocess.Popen([sys.executable, "-c", "from fastdet._numba import _worker; _worker()", *plan],
                                     stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     text=True, env=env, start_new_session=True)
            except OSError:  # no process to be had: its share compiles here afterwards
                continue
            procs.append(p)
            threading.Thread(target=_read_worker, args=(p, done), daemon=True).start()
        threading.Thread(target=_compile_here, args=(est.plan[0], done), daemon=True).start()
        show(0)
        finished = 0
        # bounded: a worker that hangs is given far more than the estimate, then left to
        # the in-process compile that follows
        deadline = time.perf_counter() + 10 * est.seconds + 120
        while finished < len(procs) + 1 and time.perf_counter() < deadline:
            try:
                kind, key, value = done.get(timeout=0.25)
            except queue.Empty:
                continue
            if kind == "done":
                times[key] = float(value)
                show(len(times))
            elif kind == "exit":
                finished += 1
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait()
    return times


def _init_compiler() -> None:
    """Have Numba set up its compiler now (:data:`COMPILER_INIT_SECONDS`), so that the
    seconds measured per kernel are the kernel's own."""
    numba.njit(cache=False)(lambda x: x + 1)(1)


def _compile_here(keys: list[str], out: queue.Queue) -> None:
    """Compile ``keys`` in this process (a helper thread: the main one shows the progress and
    stays responsive to signals); a failure is left to the caller's own compile."""
    _init_compiler()
    for key in keys:
        c0 = time.thread_time()
        try:
            Task.parse(key).dispatcher().compile(Task.parse(key).signature())
        except Exception:  # noqa: BLE001 - compiled again by ensure_compiled, where the error shows
            continue
        out.put(("done", key, time.thread_time() - c0))
    out.put(("exit", "", 0))


def _read_worker(p: subprocess.Popen, out: queue.Queue) -> None:
    assert p.stdout is not None
    for line in p.stdout:  # a failed task is compiled again in the parent, where its error shows
        parts = line.split()
        if len(parts) == 3 and parts[0] == "done":
            out.put(("done", parts[1], parts[2]))
    out.put(("exit", "", p.wait()))


def _worker() -> None:
    """Compile the tasks named on the command line into the cache; ``done KEY CPU_SECONDS`` per task."""
    parent = os.getppid()
    _init_compiler()
    for key in sys.argv[1:]:
        if os.getppid() != parent:  # the parent is gone: stop
            return
        t = Task.parse(key)
        c0 = time.thread_time()
        try:
            t.dispatcher().compile(t.signature())
        except Exception as exc:  # noqa: BLE001 - reported by the parent's own compile
            print(f"error {key} {type(exc).__name__}", flush=True)
            continue
        print(f"done {key} {time.thread_time() - c0:.3f}", flush=True)


# --------------------------------------------------------------------------------------
# threads
# --------------------------------------------------------------------------------------
_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


def split_range(fn: Callable[[int, int], None], n: int, parts: int) -> None:
    """``fn(lo, hi)`` over ``0 <= i < n`` cut into ``parts`` contiguous ranges of about equal
    length, run at once: the first on the calling thread, the others on a shared pool of
    ``NUMBA_NUM_THREADS - 1`` threads (``fn`` runs serial Numba kernels, which release the
    GIL). Returns when all are done; re-raises the first exception. ``parts <= 1``: one call
    ``fn(0, n)`` here. How the package's kernels use several cores without being
    ``parallel=True`` kernels."""
    global _pool
    parts = max(1, min(int(parts), n, numba.config.NUMBA_NUM_THREADS))
    if parts == 1:
        if n > 0:
            fn(0, n)
        return
    cuts = [n * i // parts for i in range(parts + 1)]
    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(max_workers=max(1, numba.config.NUMBA_NUM_THREADS - 1),
                                       thread_name_prefix="fastdet-rows")
        pool = _pool
    futures = [pool.submit(fn, cuts[i], cuts[i + 1]) for i in range(1, parts)]
    errors: list[BaseException] = []
    try:
        fn(cuts[0], cuts[1])
    finally:
        for f in futures:
            try:
                f.result()
            except BaseException as exc:  # noqa: BLE001 - re-raised below
                errors.append(exc)
    if errors:
        raise errors[0]

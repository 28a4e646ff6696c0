"""Compile the kernel signatures the on-disk cache lacks before a run starts
(:func:`ensure_compiled`): in worker processes, one per core, with progress shown, then
loaded here."""
from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numba

from .. import console, exiting
from .cache import failed as cache_failed
from .compile_time import WORKERS_ENV, Estimate, _save_times, _times_path, estimate
from .registry import Task, is_cached, tasks_of

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
    root = str(Path(__file__).resolve().parents[2])  # the folder holding fastdet/
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
        here = threading.Thread(target=_compile_here, args=(est.plan[0], done), daemon=True)
        here.start()
        exiting.leave_behind(here)  # inside LLVM until it ends: the process must not wait for it at exit
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
        if cache_failed() is not None:
            return  # the cache cannot be written: what this process compiles is lost with it
        print(f"done {key} {time.thread_time() - c0:.3f}", flush=True)

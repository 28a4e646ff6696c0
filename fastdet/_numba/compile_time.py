"""How long compiling some kernel signatures should take on this machine now: a speed
probe, the compile seconds measured here before (kept beside the kernels' cache), the
tasks shared out among worker processes, and the :class:`Estimate` of it all."""
from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .registry import Task
from .threads import longest_first

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
    seconds late: :func:`~.threads.longest_first`): the tasks of each worker."""
    keys = list(costs)
    plan = longest_first([costs[k] for k in keys], workers, start)
    return [[keys[i] for i in p] for p in plan if p]


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

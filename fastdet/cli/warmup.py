"""``python -m fastdet warmup [--profile]``: compile every numba kernel ahead of time.

A first run of any command compiles the kernels it needs before it starts (on every core);
``warmup`` compiles all of them now -- for a container image, a CI job or a cluster worker
that should start at full speed -- into the same on-disk cache the commands load from
(the package's ``__pycache__`` folders, the user cache folder when those are read-only, or
``NUMBA_CACHE_DIR``). Kernels already in the cache are not compiled again.

``--profile``: one line per kernel signature with its compile seconds, wall and CPU (in this
process, one after the other: how the time is spent, not how fast the parallel warm-up is;
on a busy machine the CPU seconds are the ones to compare).
"""
from __future__ import annotations

import argparse
import time

from .. import _numba, console
from ..errors import FastdetError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--profile", action="store_true",
                        help="compile one kernel signature after the other in this process and print each one's "
                             "seconds (slower: one core)")


def run(args: argparse.Namespace) -> int:
    kernels = _numba.all_kernels()
    if not args.profile:
        _numba.ensure_compiled(kernels, what="every kernel", always_report=True)
        _stored()
        return 0
    tasks = _numba.tasks_of(kernels)
    total = cpu_total = 0.0
    print(f"{'wall s':>7} {'CPU s':>7}  kernel (signature)")
    for t in tasks:
        cached = _numba.is_cached(t)
        t0, c0 = time.perf_counter(), time.thread_time()
        t.dispatcher().compile(t.signature())
        dt, cpu = time.perf_counter() - t0, time.thread_time() - c0
        total += dt
        cpu_total += cpu
        sig = ", ".join(str(a) for a in t.signature())
        print(f"{dt:7.2f} {cpu:7.2f}  {t.module.rsplit('.', 1)[-1]}.{t.name}({sig})"
              f"{'  [loaded from the cache]' if cached else ''}", flush=True)
    console.note(f"{len(tasks)} kernel signatures in {total:.1f} s wall, {cpu_total:.1f} s CPU")
    _stored()
    return 0


def _stored() -> None:
    """warmup's job is the cache: one that could not be written is its failure (exit 2), where
    another command only notes it and goes on (:mod:`fastdet._numba.cache`)."""
    why = _numba.cache_failed()
    if why is not None:
        raise FastdetError(f"the kernels compiled but could not be stored in the Numba cache ({why}); later runs "
                           "will compile them again: free space there or set NUMBA_CACHE_DIR to a writable folder")

"""Numba compile options, ahead-of-time compilation of the kernels, and the thread helper.

This package module holds the compile options and re-exports the rest: the kernel registry
(:mod:`.registry`), the compile-time estimate (:mod:`.compile_time`), the compiling
(:mod:`.compiling`), :func:`split_range` and the one-core threads (:mod:`.threads`).

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
A cache that cannot be written (a full disk, a read-only folder) is one note and the run goes
on with the code in memory (:mod:`.cache`).
"""
from __future__ import annotations

from typing import Any

from .cache import failed as cache_failed  # noqa: F401  (re-exported)
from .cache import tolerate_cache_writes
from .compile_time import (  # noqa: F401  (re-exported)
    _TIMES_FILE,
    COMPILER_INIT_SECONDS,
    LOAD_SECONDS,
    PROBE_UNIT_SECONDS,
    WORKER_START_SECONDS,
    WORKERS_ENV,
    Estimate,
    _cores,
    _load_times,
    _probe_unit,
    _save_times,
    _schedule,
    _times_path,
    _workers,
    estimate,
    machine_probe,
)
from .compiling import (  # noqa: F401  (re-exported; ``_worker`` is what a compile worker process runs)
    _compile,
    _compile_here,
    _init_compiler,
    _read_worker,
    _worker,
    ensure_compiled,
)
from .registry import KERNEL_MODULES, Task, all_kernels, is_cached, tasks_of  # noqa: F401  (re-exported)
from .threads import longest_first, serial_kernels, serial_thread, split_range  # noqa: F401  (re-exported)

tolerate_cache_writes()  # before any kernel compiles: a full or read-only cache is a note (see .cache)

EXACT: dict[str, Any] = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
REASSOC: dict[str, Any] = dict(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")

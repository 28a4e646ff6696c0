"""Numba compile options, defined once for every kernel module.

``EXACT``: IEEE arithmetic in source order (what the kernels compared bit-for-bit or to
1e-12 against scikit-image and NumPy use). ``REASSOC``: lets LLVM reassociate sums and fuse
multiply-adds so dot products vectorise (the scoring kernels, checked to 1e-6 against the
classic per-window pipeline). Every kernel caches its machine code on disk (``cache=True``:
compile cost is paid once per install; Numba falls back to a user cache folder when the
package folder is read-only) and releases the GIL (``nogil=True``) so band threads, the
reader and the writer overlap. ``*_PARALLEL`` adds ``parallel=True`` for ``prange`` kernels.

The first run on a fresh install compiles the kernels (:data:`COMPILE_SECONDS`);
:func:`announce_compile` says so once, before it starts, when a kernel has nothing in its
cache yet (looked up where Numba will look: the package's ``__pycache__``, or the user cache
folder Numba falls back to when the package folder is read-only).
"""
from __future__ import annotations

from typing import Any

from .console import note

#: about how long the first run's compilation of the detection kernels takes, in seconds (the
#: measurement: docs/reliability.md, "first run")
COMPILE_SECONDS = 15

EXACT: dict[str, Any] = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
EXACT_PARALLEL: dict[str, Any] = dict(EXACT, parallel=True)
REASSOC: dict[str, Any] = dict(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")
REASSOC_PARALLEL: dict[str, Any] = dict(REASSOC, parallel=True)
REASSOC_INLINE: dict[str, Any] = dict(REASSOC, inline="always")


def cached(dispatcher: Any) -> bool:
    """``dispatcher`` (a ``cache=True`` Numba function) has machine code in its on-disk cache
    for this source (any signature); ``True`` when that cannot be told."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - Numba internals: when in doubt, say nothing
        return True


def announce_compile(*dispatchers: Any, what: str = "the detection kernels") -> bool:
    """Print once per process that ``what`` are being compiled when one of ``dispatchers``
    has no cached code (a first run); returns whether it did."""
    if all(cached(d) for d in dispatchers):
        return False
    note(f"compiling {what} (first run only, about {COMPILE_SECONDS} s; later runs load them from the cache)",
         once="compile")
    return True

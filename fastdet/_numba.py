"""Numba compile options, defined once for every kernel module.

``EXACT``: IEEE arithmetic in source order (what the kernels compared bit-for-bit or to
1e-12 against scikit-image and NumPy use). ``REASSOC``: lets LLVM reassociate sums and fuse
multiply-adds so dot products vectorise (the scoring kernels, checked to 1e-6 against the
classic per-window pipeline). Every kernel caches its machine code on disk (``cache=True``:
compile cost is paid once per install; Numba falls back to a user cache folder when the
package folder is read-only) and releases the GIL (``nogil=True``) so band threads, the
reader and the writer overlap. ``*_PARALLEL`` adds ``parallel=True`` for ``prange`` kernels.
"""
from __future__ import annotations

from typing import Any

EXACT: dict[str, Any] = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
EXACT_PARALLEL: dict[str, Any] = dict(EXACT, parallel=True)
REASSOC: dict[str, Any] = dict(cache=True, nogil=True, fastmath={"reassoc", "contract"}, error_model="numpy")
REASSOC_PARALLEL: dict[str, Any] = dict(REASSOC, parallel=True)
REASSOC_INLINE: dict[str, Any] = dict(REASSOC, inline="always")

"""A Numba cache that cannot be written costs a compile, not the run.

Every kernel caches its machine code on disk (``cache=True``). Numba picks a folder it can
write when the function is first compiled (``NUMBA_CACHE_DIR``, else the package's
``__pycache__``, else the user cache folder), but the *save* after a compile is not guarded:
a disk that is full (``ENOSPC``), a quota (``EDQUOT``), a folder made read-only meanwhile
(``EROFS``, ``EACCES``) raised Numba's ``OSError`` traceback out of ``warmup`` or a first
``video`` run (issue 34, item 13).

The compiled code is in memory before the save is tried (Numba adds the overload first), so
the run does not need the cache: :func:`tolerate_cache_writes` makes a failed save one note,
once per process -- "cannot write the compiled kernels to the Numba cache ... this run uses
them from memory; later runs compile them again until the cache can be written" -- and the
run goes on. A warning and going on, not an error: the user's command and inputs are fine,
only the next start-up is slower; an error would stop a run that can finish (a video whose
outputs go to another disk). ``warmup``, whose whole job is the cache, says at the end that
nothing was stored (:func:`failed`) and exits 2. When no folder at all can be written (a
read-only container: Numba's ``RuntimeError: ... no locator available`` when a kernel module
was imported), the kernels are compiled without a cache, after one note. The save's own partial files are removed by
Numba (``_open_for_write``).
"""
from __future__ import annotations

import errno
import functools
import os
from typing import Any

from .. import console

#: errors of the place written to: the cache is skipped, the run goes on
CACHE_WRITE_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG,
                                errno.ENAMETOOLONG, errno.EIO})
_failures: list[str] = []


def failed() -> str | None:
    """Why the first save into the cache failed in this process (``None``: none did)."""
    return _failures[0] if _failures else None


def _cache_path(cache: Any) -> str:
    try:
        return str(cache.cache_path)
    except Exception:  # noqa: BLE001 - only for the message
        return "the Numba cache"


def tolerate_cache_writes() -> None:
    """Wrap Numba's ``Cache.save_overload`` (idempotent; nothing when Numba has no such
    method): a save failing with one of :data:`CACHE_WRITE_ERRORS` is one note, not an
    exception."""
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover - numba is a dependency
        return
    save = getattr(caching.Cache, "save_overload", None)
    if save is None or getattr(save, "_fastdet_tolerant", False):
        return

    @functools.wraps(save)
    def save_overload(self: Any, sig: Any, data: Any) -> None:
        try:
            save(self, sig, data)
        except OSError as exc:
            if exc.errno not in CACHE_WRITE_ERRORS:
                raise
            why = exc.strerror or str(exc)
            _failures.append(why)
            console.note(f"cannot write the compiled kernels to the Numba cache at {_cache_path(self)} ({why}): "
                         "this run uses them from memory; later runs compile them again until the cache can be "
                         "written (free space there, or set NUMBA_CACHE_DIR to a writable folder)",
                         once="numba-cache-write")

    save_overload._fastdet_tolerant = True  # type: ignore[attr-defined]
    caching.Cache.save_overload = save_overload  # type: ignore[method-assign]
    _tolerate_no_cache_folder()


def _tolerate_no_cache_folder() -> None:
    """Numba's ``Dispatcher.enable_caching`` (``cache=True``, when a kernel module is imported)
    raised ``RuntimeError: cannot cache function ...: no locator available`` when no folder can
    be written -- ``NUMBA_CACHE_DIR`` read-only or full, the package read-only, no writable user
    cache folder (a read-only container) -- a traceback before any work. The kernel is then
    compiled without a cache (Numba's ``NullCache``), after one note."""
    try:
        from numba.core.dispatcher import Dispatcher
    except ImportError:  # pragma: no cover - numba is a dependency
        return
    enable = getattr(Dispatcher, "enable_caching", None)
    if enable is None or getattr(enable, "_fastdet_tolerant", False):
        return

    @functools.wraps(enable)
    def enable_caching(self: Any) -> None:
        try:
            enable(self)
        except RuntimeError as exc:
            if "no locator available" not in str(exc):
                raise
            _failures.append("no folder can be written")
            where = os.environ.get("NUMBA_CACHE_DIR") or "NUMBA_CACHE_DIR (unset)"
            console.note(f"no folder for the Numba cache can be written ({where}, the package's __pycache__, the "
                         "user cache folder): the kernels are compiled in memory, on every run; set NUMBA_CACHE_DIR "
                         "to a writable folder", once="numba-cache-folder")

    enable_caching._fastdet_tolerant = True  # type: ignore[attr-defined]
    Dispatcher.enable_caching = enable_caching  # type: ignore[method-assign]

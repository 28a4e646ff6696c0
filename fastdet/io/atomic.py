"""Outputs that appear under their final name only when complete.

Every file fastdet writes (models, videos, images, box files, plots, manifests) is written to
a hidden temporary name in the destination folder (:func:`partial_name`) and renamed with
``os.replace`` (atomic on POSIX within one file system) when it is complete. A run that
fails or is stopped leaves no file under the final name that looks complete.
"""
from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import DataError


def partial_name(path: str | os.PathLike) -> Path:
    """Temporary name of an output while it is written: ``dir/.NAME.partial.EXT`` (the
    extension is kept: OpenCV picks the container / image format from it)."""
    p = Path(path)
    return p.with_name(f".{p.stem}.partial{p.suffix}")


def _unlink_quietly(p: Path) -> None:
    try:
        p.unlink(missing_ok=True)
    except OSError:
        pass


def commit(tmp: str | os.PathLike, path: str | os.PathLike, mode: int | None = 0o644) -> Path:
    """Give the finished temporary file ``tmp`` its final name ``path``; ``DataError`` (and
    ``tmp`` removed) when the rename fails."""
    tmp, path = Path(tmp), Path(path)
    try:
        if mode is not None:
            os.chmod(tmp, mode)
        os.replace(tmp, path)
    except OSError as exc:
        _unlink_quietly(tmp)
        raise DataError(f"{path}: cannot write ({exc.strerror or exc})") from None
    return path


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """``with atomic_path(out) as tmp:`` write ``tmp``; on a normal exit it becomes ``out``,
    on an exception (or a signal turned into one) it is removed and ``out`` is untouched.

    An ``OSError`` while writing becomes a one-line :class:`~fastdet.errors.DataError`
    naming ``out`` (not the temporary name)."""
    path = Path(path)
    tmp = partial_name(path)
    try:
        yield tmp
    except OSError as exc:
        _unlink_quietly(tmp)
        raise DataError(f"{path}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        _unlink_quietly(tmp)
        raise
    if not tmp.exists():
        raise DataError(f"{path}: nothing was written")
    commit(tmp, path)


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    return Path(path)


def folder_writable(folder: str | os.PathLike) -> bool:
    """A file can be created in ``folder`` (tried: ``os.access`` says yes to root on a
    read-only mount)."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".fastdet-probe-", dir=folder)
    except OSError:
        return False
    os.close(fd)
    _unlink_quietly(Path(probe))
    return True


def check_output_path(path: str | os.PathLike, what: str, inp: str | os.PathLike | None = None) -> None:
    """Refuse an output location before any work: folder missing or not writable, a folder
    given as a file name, or the output being the input itself."""
    path = os.fspath(path)
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise DataError(f"{path}: output folder {parent} does not exist")
    if not folder_writable(parent):
        raise DataError(f"{path}: output folder {parent} is not writable")
    if os.path.isdir(path):
        raise DataError(f"{path}: is a folder, expected a {what} file name")
    if inp is not None and os.path.exists(path) and os.path.exists(inp) and os.path.samefile(path, inp):
        raise DataError(f"{path}: the {what} would overwrite the input")

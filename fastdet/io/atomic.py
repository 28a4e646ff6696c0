"""Outputs that appear under their final name only when complete.

Every file fastdet writes (models, videos, images, box files, plots, manifests) is written to
a hidden temporary name in the destination folder (:func:`partial_name`) and renamed with
``os.replace`` (atomic on POSIX within one file system) when it is complete. A run that
fails or is stopped leaves no file under the final name that looks complete.

The temporary name holds the process id and a random token (:func:`process_token`), so two
runs writing the same output never share a temporary file: each writes its own, the last
rename wins whole, and a run removes only its own temporary files. :class:`OutputSet`
renames a run's outputs together, after all of them were written, or removes them all.
"""
from __future__ import annotations

import os
import secrets
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import DataError, WriteError

_token: tuple[int, str] | None = None


def process_token() -> str:
    """``PID-RANDOM``: unique to this process (made anew in a forked child)."""
    global _token
    pid = os.getpid()
    if _token is None or _token[0] != pid:
        _token = (pid, f"{pid}-{secrets.token_hex(4)}")
    return _token[1]


def partial_name(path: str | os.PathLike) -> Path:
    """Temporary name of an output while this process writes it:
    ``dir/.NAME.partial.PID-RANDOM.EXT`` (:func:`process_token`; the extension is kept:
    OpenCV picks the container / image format from it)."""
    p = Path(path)
    return p.with_name(f".{p.stem}.partial.{process_token()}{p.suffix}")


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
        raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
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
        raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
    except BaseException:
        _unlink_quietly(tmp)
        raise
    if not tmp.exists():
        raise WriteError(f"{path}: nothing was written")
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


class OutputSet:
    """A run's outputs, renamed together when all are complete.

    ``add(tmp, final)`` records a finished temporary file; :meth:`commit` gives every one its
    final name (in the order added) and :meth:`discard` removes them all. A failed rename
    removes the temporary files not yet renamed and the outputs this set already renamed,
    so a failed run keeps none of its outputs (a file an earlier run left under a final
    name that this run had not yet replaced stays).
    """

    def __init__(self) -> None:
        self._pending: list[tuple[Path, Path]] = []

    def add(self, tmp: str | os.PathLike, final: str | os.PathLike) -> None:
        self._pending.append((Path(tmp), Path(final)))

    def __len__(self) -> int:
        return len(self._pending)

    def finals(self) -> list[Path]:
        return [f for _, f in self._pending]

    def commit(self) -> list[Path]:
        """Rename all; ``WriteError`` (and nothing of this set left) when one fails."""
        done: list[Path] = []
        pending, self._pending = self._pending, []
        for k, (tmp, final) in enumerate(pending):
            try:
                commit(tmp, final)
            except DataError:
                for t, _ in pending[k + 1:]:
                    _unlink_quietly(t)
                for f in done:
                    _unlink_quietly(f)
                raise
            done.append(final)
        return done

    def discard(self) -> None:
        pending, self._pending = self._pending, []
        for tmp, _ in pending:
            _unlink_quietly(tmp)

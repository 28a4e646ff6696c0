"""Outputs that appear under their final name only when complete.

Every file fastdet writes (models, videos, images, box files, plots, manifests) is written to
a hidden temporary name in the destination folder (:func:`partial_name`) and renamed with
``os.replace`` (atomic on POSIX within one file system) when it is complete. A run that
fails or is stopped leaves no file under the final name that looks complete.

The temporary name holds the process id and a random token (:func:`process_token`), so two
runs writing the same output never share a temporary file: each writes its own, the last
rename wins whole, and a run removes only its own temporary files. :class:`OutputSet`
renames a run's outputs together, after all of them were written, or removes them all.

Every temporary name this process hands out is remembered until it is renamed or removed;
:func:`remove_partials` removes what is left when the process ends (``atexit``, and
:mod:`fastdet.__main__` before it exits without the interpreter's teardown), so no exit path
-- a second Ctrl-C that cut a clean-up short, an exception out of a library -- leaves a
``.NAME.partial.PID-TOKEN.EXT`` behind. Only SIGKILL does (nothing runs then).
"""
from __future__ import annotations

import atexit
import os
import secrets
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import DataError, WriteError

_token: tuple[int, str] | None = None
#: the temporary names this process handed out and has not yet renamed or removed (a forked
#: child starts with none: the parent's are the parent's)
_own: tuple[int, set[Path]] = (os.getpid(), set())


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
    tmp = p.with_name(f".{p.stem}.partial.{process_token()}{p.suffix}")
    _owned().add(tmp)
    return tmp


def _owned() -> set[Path]:
    global _own
    if _own[0] != os.getpid():
        _own = (os.getpid(), set())
    return _own[1]


def _unlink_quietly(p: Path) -> None:
    try:
        p.unlink(missing_ok=True)
    except OSError:
        pass
    _owned().discard(p)


def discard_partial(tmp: str | os.PathLike) -> None:
    """Remove a temporary file of :func:`partial_name` that is not to become an output (a
    scratch file: frames held for a few passes); quiet when it is gone already."""
    _unlink_quietly(Path(tmp))


def remove_partials() -> None:
    """Remove every temporary file of this process still under its temporary name (see the
    module docstring); run at exit."""
    for p in list(_owned()):
        _unlink_quietly(p)


atexit.register(remove_partials)


def current_umask() -> int:
    """The process's umask (read from ``/proc/self/status`` where it can be: setting it to
    read it back is not thread-safe; else set and restored at once)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    old = os.umask(0o022)
    os.umask(old)
    return old


def output_mode(path: str | os.PathLike) -> int:
    """The permission bits an output written to ``path`` gets: those of the regular file it
    replaces, else what ``open()`` gives a new file (``0o666`` less the umask)."""
    try:
        st = os.stat(path)
    except OSError:
        st = None
    if st is not None and stat.S_ISREG(st.st_mode):
        return stat.S_IMODE(st.st_mode)
    return 0o666 & ~current_umask()


def commit(tmp: str | os.PathLike, path: str | os.PathLike, mode: int | None = None) -> Path:
    """Give the finished temporary file ``tmp`` its final name ``path``; ``DataError`` (and
    ``tmp`` removed) when the rename fails. ``mode``: its permission bits (default
    :func:`output_mode`: the replaced file's, or ``0o666`` less the umask for a new one, as
    any program's ``open()`` would give; the temporary file may have been made otherwise)."""
    tmp, path = Path(tmp), Path(path)
    try:
        os.chmod(tmp, output_mode(path) if mode is None else mode)
        os.replace(tmp, path)
    except OSError as exc:
        _unlink_quietly(tmp)
        raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
    _owned().discard(tmp)
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


@contextmanager
def new_folders(folder: str | os.PathLike) -> Iterator[list[Path]]:
    """``with new_folders(out):`` makes ``out`` and its missing parents (an ``OSError`` as
    ``mkdir`` raises it) and yields the folders it made, outermost first. When the block ends
    in an exception (a failed start, a stop signal), the folders made here that are still empty
    are removed, innermost first: a run that fails leaves no folder it made. A folder that
    existed before stays, and so does one that holds anything (a file of this run or of
    another's: only ``rmdir``, which removes empty folders only)."""
    target = Path(os.path.abspath(folder))
    missing: list[Path] = []
    p = target
    while not os.path.lexists(p) and p != p.parent:
        missing.append(p)
        p = p.parent
    made: list[Path] = []
    try:
        for d in reversed(missing):
            try:
                os.mkdir(d)
            except FileExistsError:
                if not d.is_dir():
                    raise
                continue  # made meanwhile by someone else: theirs
            made.append(d)
        if not target.is_dir():
            os.mkdir(target)  # a dangling symlink, a symlink loop: mkdir's own error
        yield list(made)
    except BaseException:
        remove_empty_folders(made)
        raise


def remove_empty_folders(folders: list[Path]) -> None:
    """``rmdir`` each of ``folders`` (outermost first, as :func:`new_folders` yields them),
    innermost first, where it is empty; any other is left as it is."""
    for d in reversed(folders):
        try:
            os.rmdir(d)
        except OSError:
            pass


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

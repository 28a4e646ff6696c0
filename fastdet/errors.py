"""Exceptions that mean "the user gave us something wrong" (one-line message, no traceback),
and the one-line error for an input path that cannot be reached (:func:`not_found`)."""
from __future__ import annotations

import errno
import os


class FastdetError(Exception):
    """A user-facing error: the CLI prints ``fastdet: <message>`` and exits non-zero."""


class ModelError(FastdetError, ValueError):
    """A model file is missing, malformed, of another format version or another feature config."""


class DataError(FastdetError, ValueError):
    """An input file (video, image, annotation, data folder) is missing or malformed."""


class WriteError(DataError):
    """Writing an output failed (a full disk, a temporary file that vanished, no
    permission): a fault of the place written to, not of the input; retrying may succeed."""


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message, for a summary or a manifest: a
    :class:`FastdetError`'s message as it is, any other exception prefixed with its type
    (``KeyError: 'x'``); the type alone when the message is empty."""
    text = str(exc).strip()
    if not text:
        return type(exc).__name__
    first = text.splitlines()[0]
    return first if isinstance(exc, FastdetError) else f"{type(exc).__name__}: {first}"


def stat_error(name: str, exc: OSError) -> DataError:
    """The one-line :class:`DataError` for a failed ``stat`` / ``open`` of the input ``name``."""
    if exc.errno == errno.ELOOP:
        return DataError(f"{name}: symlink loop (the link leads back to itself; too many levels of "
                         f"symbolic links)")
    if exc.errno in (errno.ENOENT, errno.ENOTDIR):
        return DataError(f"{name}: file not found")
    if exc.errno == errno.ENAMETOOLONG:
        return DataError(f"{name}: file name too long")
    return DataError(f"{name}: cannot read ({exc.strerror or exc})")


def not_found(path: str | os.PathLike[str], message: str) -> DataError:
    """The error for ``path`` found missing (``os.path.exists`` / ``is_file`` / ``is_dir`` said
    no): ``message`` when it is absent, else why it cannot be reached -- a symlink loop
    ("symlink loop", not "file not found": ``exists`` is ``False`` for both), a name too long,
    no permission (:func:`stat_error`)."""
    name = os.fspath(path)
    try:
        os.stat(name)
    except OSError as exc:
        if exc.errno not in (errno.ENOENT, errno.ENOTDIR):
            return stat_error(name, exc)
    return DataError(message)

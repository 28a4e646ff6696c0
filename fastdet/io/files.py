"""Input files, opened one way: :func:`check_input`, :func:`open_input`, :func:`read_input_bytes`,
:func:`read_input_text`.

Every input that fastdet reads as a file (a picture, a training crop, ground truth,
predictions, a keyframe list, a label file, a model, the batch manifest) goes through
:func:`check_input` before it is opened:

- a missing file says "file not found", a symlink loop says "symlink loop" (``os.path.exists``
  is ``False`` for both);
- anything that is not a regular file -- a named pipe (FIFO), a device (``/dev/zero``), a
  socket, a folder -- is refused in one line *before* the open: opening a FIFO for reading
  waits until a writer comes, for ever, and reading a device may never end. (Video is the one
  input that may be a pipe or a device: :mod:`fastdet.io.reader` opens those as live sources,
  with its own bounded wait.)

:func:`open_input` then opens with ``O_NONBLOCK`` (a FIFO swapped in after the check cannot
block the open either) and checks the open file again; :func:`read_input_bytes` reads at most
a size bound (a 3 GB binary handed over as ground truth is refused from its size, before a
byte is read), and :func:`read_input_text` refuses binary data (a NUL byte) at once.
"""
from __future__ import annotations

import json
import os
import stat
from typing import Any, BinaryIO

from ..errors import DataError, not_found, stat_error  # noqa: F401  (re-exported)

#: the largest text input (ground truth, predictions, keyframe lists, label files, the
#: batch manifest): 128 MB, about 3 million box lines (parsed, a line takes some 10 times its bytes)
MAX_TEXT_BYTES = 128 * 2**20
_HEAD = 64 * 1024


def _kind(mode: int) -> str:
    if stat.S_ISFIFO(mode):
        return "a named pipe (FIFO)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _a(what: str) -> str:
    return f"{'an' if what[:1].lower() in 'aeiou' else 'a'} {what}"


def check_input(path: str | os.PathLike[str], what: str = "file") -> os.stat_result:
    """``path``'s ``stat`` when it is a regular file; :class:`DataError` (one line: "file not
    found", "symlink loop", "is a folder", "is a named pipe (FIFO) ...") otherwise. Nothing is
    opened."""
    name = os.fspath(path)
    try:
        st = os.stat(name)
    except OSError as exc:
        raise stat_error(name, exc) from None
    if stat.S_ISDIR(st.st_mode):
        raise DataError(f"{name}: is a folder, expected {_a(what)} file")
    if not stat.S_ISREG(st.st_mode):
        raise DataError(f"{name}: is {_kind(st.st_mode)}, not a regular file; {_a(what)} is read "
                        f"from a file only")
    return st


def open_input(path: str | os.PathLike[str], what: str = "file") -> BinaryIO:
    """``path`` opened for reading (binary) after :func:`check_input`; the open never waits
    (``O_NONBLOCK``) and the opened file is checked to be regular again."""
    name = os.fspath(path)
    check_input(name, what)
    try:
        fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise stat_error(name, exc) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise DataError(f"{name}: is {_kind(st.st_mode)}, not a regular file; {_a(what)} is read "
                            f"from a file only")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _mb(n: int) -> str:
    return f"{n / 2**20:.0f} MB" if n >= 2**20 else f"{n} bytes"


def _not_text(name: str, nul: int) -> DataError:
    return DataError(f"{name}: not a text file (binary data: a NUL byte at byte {nul})")


def read_input_bytes(path: str | os.PathLike[str], what: str = "file", limit: int = MAX_TEXT_BYTES,
                     text: bool = False) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_input`), at most ``limit`` of them:
    a larger file is refused from its size before it is read (and a file that grows past the
    bound while read is refused too). ``text``: a NUL byte in the first 64 KB refuses the
    file as binary before the rest is read."""
    name = os.fspath(path)
    with open_input(name, what) as fh:
        size = os.fstat(fh.fileno()).st_size
        if size > limit:
            raise DataError(f"{name}: is {_mb(size)}, larger than {_a(what)} may be ({_mb(limit)})")
        try:
            data = fh.read(min(limit + 1, _HEAD))
            if text and b"\0" in data:
                raise _not_text(name, data.find(b"\0"))
            if len(data) == _HEAD:
                data += fh.read(limit + 1 - len(data))
        except OSError as exc:
            raise DataError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise DataError(f"{name}: is larger than {_a(what)} may be ({_mb(limit)})")
    return data


def read_input_text(path: str | os.PathLike[str], what: str = "text file", limit: int = MAX_TEXT_BYTES) -> str:
    """The text (UTF-8, a BOM allowed, newlines as Python reads them) of the regular file
    ``path``, at most ``limit`` bytes (:func:`read_input_bytes`); :class:`DataError` "not a text
    file" for binary data (a NUL byte, or bytes that are not UTF-8)."""
    name = os.fspath(path)
    data = read_input_bytes(name, what, limit, text=True)
    nul = data.find(b"\0")
    if nul >= 0:
        raise _not_text(name, nul)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataError(f"{name}: not a text file ({exc.reason} at byte {exc.start})") from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


class JsonError(ValueError):
    """JSON text that does not parse; the message is the reason in a few words (``line 3: Expecting
    value, column 5``, ``nested too deeply``), for the caller to put after the file's name."""


def parse_json(text: str | bytes) -> Any:
    """``json.loads(text)`` whose every failure on input text is a :class:`JsonError`: a syntax
    error, nesting deeper than the interpreter's recursion limit (``RecursionError``: 200,000
    ``[``), an integer of more than 4,300 digits (Python's ``int_max_str_digits``, a plain
    ``ValueError``), bytes that are not UTF-8. One place for every JSON input (COCO files, JSON-lines
    boxes, the batch manifest, model metadata), so none of them shows a traceback for a file."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise JsonError(f"line {exc.lineno}: {exc.msg}, column {exc.colno}") from None
    except RecursionError:
        raise JsonError("nested too deeply") from None
    except UnicodeDecodeError as exc:
        raise JsonError(f"not UTF-8 ({exc.reason} at byte {exc.start})") from None
    except ValueError as exc:  # int_max_str_digits
        why = str(exc).split(";")[0]
        raise JsonError(f"a number too long ({why})") from None

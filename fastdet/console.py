"""What fastdet says on stderr besides errors: one-line notes, and silence from the libraries.

- :func:`note` prints ``PROG: MESSAGE`` on stderr, where ``PROG`` is ``fastdet`` or, once
  the CLI chose a command, ``fastdet COMMAND`` (:func:`set_prog`); with ``once=KEY`` a
  note is printed only the first time in a process (the kernel-compile notice, a grey
  input).
- :func:`status` shows a line that changes as work goes on (the kernel compile's
  progress): rewritten in place on a terminal; elsewhere only its final state is printed.
- :func:`quiet_native_stderr` silences what C libraries write straight to file descriptor 2
  (libjpeg's "Premature end of JPEG file", FFmpeg's encoder list for an unknown codec)
  for the duration of a call: fastdet reports those cases itself, in one line.
- :func:`quiet_opencv` turns off OpenCV's own log lines (``[ WARN:0@0.01] global ...``)
  and FFmpeg's (``OPENCV_FFMPEG_LOGLEVEL``) unless the user set them.
"""
from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import cv2

_prog = "fastdet"
_t_import = time.perf_counter()
_said: set[str] = set()
_fd_lock = threading.Lock()


def set_prog(prog: str) -> None:
    """Name the notes carry (``fastdet video``)."""
    global _prog
    _prog = prog


def prog() -> str:
    return _prog


def process_seconds() -> float:
    """Wall seconds since this process started (Linux: from ``/proc``; elsewhere since
    fastdet was imported), for "N s in all" in the summaries."""
    try:
        with open("/proc/self/stat", "rb") as fh:
            start_ticks = int(fh.read().rsplit(b")", 1)[1].split()[19])
        with open("/proc/uptime", "rb") as fh:
            uptime = float(fh.read().split()[0])
        return max(uptime - start_ticks / os.sysconf("SC_CLK_TCK"), 0.0)
    except (OSError, ValueError, IndexError):
        return time.perf_counter() - _t_import


def note(message: str, once: str | None = None) -> None:
    """Print ``PROG: message`` on stderr (only the first time for a given ``once`` key)."""
    if once is not None:
        if once in _said:
            return
        _said.add(once)
    try:
        print(f"{_prog}: {message}", file=sys.stderr, flush=True)
    except (OSError, ValueError):  # stderr closed (a hung-up terminal): nothing to tell
        pass


def status(message: str, final: bool = False) -> None:
    """``PROG: message`` as a progress line on stderr: on a terminal each call rewrites the
    line (``final`` ends it); elsewhere (a log, a pipe) only the ``final`` message is printed."""
    try:
        tty = sys.stderr.isatty()
        if tty:
            print(f"\r{_prog}: {message}\x1b[K", end="\n" if final else "", file=sys.stderr, flush=True)
        elif final:
            print(f"{_prog}: {message}", file=sys.stderr, flush=True)
    except (OSError, ValueError):  # stderr closed: nothing to tell
        pass


def quiet_opencv() -> None:
    """OpenCV and its FFmpeg backend log nothing unless the user's environment says otherwise."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
    if os.environ["OPENCV_LOG_LEVEL"].upper() == "SILENT":
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)


@contextmanager
def quiet_native_stderr() -> Iterator[None]:
    """Within the block, file descriptor 2 goes to ``/dev/null`` (what native code writes
    there is lost; Python's ``sys.stderr`` is flushed first). Keep the block short: it
    silences every thread. ``FASTDET_DEBUG=1`` leaves stderr alone."""
    if os.environ.get("FASTDET_DEBUG", "") not in ("", "0"):
        yield
        return
    with _fd_lock:
        try:
            sys.stderr.flush()
        except (OSError, ValueError):
            pass
        try:
            saved = os.dup(2)
        except OSError:
            yield
            return
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(devnull, 2)
            finally:
                os.close(devnull)
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)

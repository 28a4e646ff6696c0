"""Threads left blocked in native code, and how the process then ends.

A helper thread that waits inside OpenCV (opening a stream that never answers, reading a
stalled one, writing a video) cannot be interrupted; fastdet gives up on it after a bounded
wait and leaves it behind (:func:`leave_behind`). If the interpreter then shuts down normally,
such a thread wakes inside C++ code after Python's teardown began, is ended with
``pthread_exit`` while C++ frames are on its stack, and the C++ runtime aborts the process:
"terminate called without an active exception", exit status 134, after the command's one line
(issue 34, item 9). :func:`exit_now` ends the process instead without that teardown -- after
flushing standard output and error and removing the temporary files of this process
(:func:`fastdet.io.atomic.remove_partials`) -- with the command's own status.
:mod:`fastdet.__main__` calls it when :func:`threads_left` says a thread is still there.
"""
from __future__ import annotations

import os
import sys
import threading

_left: list[threading.Thread] = []


def leave_behind(thread: threading.Thread) -> None:
    """``thread`` (a daemon) may be inside native code when the process ends: one given up on
    after a bounded wait, or a worker (the decoder, the encoder) whose owner's clean-up was cut
    short. A thread that has ended by then changes nothing."""
    _left[:] = [t for t in _left if t.is_alive()]
    _left.append(thread)


def threads_left() -> bool:
    """A thread given up on (:func:`leave_behind`) is still running."""
    _left[:] = [t for t in _left if t.is_alive()]
    return bool(_left)


def exit_now(status: int) -> None:
    """Flush standard output and error, remove this process's temporary files and end the
    process with ``status`` at once (``os._exit``: no interpreter teardown)."""
    try:
        for stream in (sys.stdout, sys.stderr):
            try:
                if stream is not None:
                    stream.flush()
            except (OSError, ValueError):
                pass
        atomic = sys.modules.get("fastdet.io.atomic")
        if atomic is not None:
            atomic.remove_partials()
    finally:
        os._exit(status)

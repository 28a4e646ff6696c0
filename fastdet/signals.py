"""Every way a process is told to stop: Ctrl-C (SIGINT), SIGTERM, SIGHUP -- one module for
the commands and the batch.

``timeout``, ``kill``, closing the terminal, ``docker stop`` and systemd all send SIGTERM
or SIGHUP; they are handled like Ctrl-C. The dispatcher (:mod:`fastdet.cli.main`) runs
every command inside :func:`handled`; a command then only decides *where* it may stop:

- Anywhere (loading a model, compiling kernels, training): a signal raises
  :class:`Stopped` (a ``KeyboardInterrupt``) at once in the main thread; ``finally``
  blocks and :func:`fastdet.io.atomic.atomic_path` remove the partial outputs.
- Between frames: inside ``with deferred():`` a signal only sets a flag; the loop asks
  :func:`stop_requested` once per frame, finishes the frame it is on, leaves the loop and
  closes (renames) its outputs; leaving the block then raises :class:`Stopped`. A second
  signal while the flag is set raises at once (an impatient second Ctrl-C).
- Once a :class:`Stopped` is raised, a later signal while it is being handled (the ``except``
  and ``finally`` blocks that close and remove the outputs) is ignored: the clean-up is bounded
  by its own timeouts and must not be cut short (a second Ctrl-C 0.02 s after the first). Only
  a third repeat of it stops the clean-up too (:data:`IGNORED_REPEATS`).
- A :class:`Stopped` raised where Python cannot propagate it (a ``__del__``, a ctypes callback
  inside the Numba compiler) is not printed as "Exception ignored": the signal is raised again
  and lands in the code that runs next.
- A :class:`Stopped` is not raised inside locking code: that of ``threading``, ``queue``,
  ``concurrent.futures`` and ``multiprocessing.synchronize`` (a queue's ``get``, a future's
  ``result``, the process lock ``numba.get_num_threads`` takes) and any ``__enter__`` or
  ``__exit__``. Raised there, between a lock's acquire and the ``with`` that releases it, it
  left the lock held for good, and every later wait for it -- the clean-up's, a worker
  thread's, the interpreter's exit joining that worker -- never ended. The signal is raised
  again a few milliseconds later, in the code that runs next. A thread's ``join`` is not put
  off, and a stop put off for :data:`PUT_OFF_S` (a wait there that does not end) is raised
  where it lands.
- A long step that may swallow an exception (third-party code) is followed by
  :func:`check`, which raises :class:`Stopped` when a signal came meanwhile.

Batches (:mod:`fastdet.batch.job`) use the same module: ``deferred(repeats=False)`` keeps a
second signal from interrupting their bounded clean-up, and :func:`wait` is every wait that
must wake on a stop (a scheduler that does not answer, a closing client).

The dispatcher turns :class:`Stopped` -- and any other exception raised after a signal
came, e.g. from inside a compiler that was interrupted -- into one line
``fastdet COMMAND: interrupted (SIGTERM)[; detail]`` and exit status ``128 + signal``
(130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP). A command may set
:attr:`Stopped.detail` (e.g. the frames done and the files written) before re-raising.

Handlers are installed only in the main thread, and the previous ones are restored when
:func:`handled` ends (so calling ``main()`` from tests leaves the test runner as it was).

A signal that is ignored when :func:`handled` starts stays ignored: a process started with
SIGINT ignored (a background job ``fastdet video ... &`` of a shell script: POSIX shells start
those with SIGINT and SIGQUIT ignored; ``nohup`` ignores SIGHUP) keeps ignoring it for its whole
life, as its parent meant -- Python itself and the start-up handlers in ``fastdet/__init__.py``
keep an inherited ``SIG_IGN`` too (issue 34). The other stop signals still stop it.
"""
from __future__ import annotations

import _thread
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

#: the signals that stop a command
STOP_SIGNALS: tuple[int, ...] = tuple(s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None))
                                      if s is not None)

_received: int | None = None
_deferring = 0
_patient = 0  # deferred blocks in which repeated signals are ignored too
_active = 0  # handled() blocks entered (nested ones are no-ops)
_in_hook = False  # the unraisable hook runs (a Stopped raised there would be lost again)
_ignored: list[int] = []  # signals ignored while a Stopped was being handled
#: repeats of a signal ignored while its clean-up runs; the one after stops at once (a clean-up
#: that hangs -- a write to a dead network disk -- can still be ended; the temporary files are
#: then removed at exit, fastdet.io.atomic)
IGNORED_REPEATS = 2
#: the modules whose locking code a :class:`Stopped` is not raised in (:func:`_in_locking_code`)
LOCKING_MODULES = frozenset({"threading", "queue", "concurrent.futures._base", "concurrent.futures.thread",
                             "multiprocessing.synchronize"})
#: their functions a :class:`Stopped` is raised in all the same: a thread's join, which restores
#: its lock itself when interrupted (so a clean-up that waits for a hung thread can still be ended)
_INTERRUPTIBLE = frozenset({("threading", "join"), ("threading", "_wait_for_tstate_lock")})
#: seconds a stop may be put off while the main thread stays in that code; then it is raised there
#: anyway (a wait there that does not end must still be stoppable)
PUT_OFF_S = 0.5
_put_off_since: float | None = None  # when the stop being put off was first put off


class Stopped(KeyboardInterrupt):
    """A stop signal, raised in the main thread. ``signum``; ``exit_status`` = 128 + signum;
    ``name`` (``'SIGTERM'``); ``detail``: what was done, for the one-line message."""

    def __init__(self, signum: int, detail: str = "") -> None:
        super().__init__(signum)
        self.signum = signum
        self.detail = detail

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name

    @property
    def exit_status(self) -> int:
        return 128 + self.signum


def _handler(signum: int, frame: FrameType | None) -> None:
    global _received, _put_off_since
    first = _received is None
    if first:
        _received = signum
    if _deferring and (first or _patient):
        _put_off_since = None
        return  # the loop stops after its current frame (a patient block: after its clean-up)
    if not first and _unwinding() and _ignored.count(signum) < IGNORED_REPEATS:
        _ignored.append(signum)
        _put_off_since = None
        return  # a Stopped is being handled (its clean-up runs): a second one would cut it short
    if _in_hook:
        _raise_again(signum)  # inside the unraisable hook: raised where it can propagate
        return
    if _in_locking_code(frame):
        now = time.monotonic()
        _put_off_since = now if _put_off_since is None else _put_off_since
        if now - _put_off_since < PUT_OFF_S:
            _raise_again(signum)  # raised in the code that runs next, once out of the lock's code
            return
    _put_off_since = None
    raise Stopped(signum)


def _in_locking_code(frame: FrameType | None) -> bool:
    """``frame`` (where the main thread is as the handler runs) is code of
    :data:`LOCKING_MODULES` or a context manager's ``__enter__`` / ``__exit__``. An exception
    raised there at an arbitrary bytecode can fall between a lock's acquire and the ``with`` or
    ``try`` that releases it -- ``Condition.__enter__`` or ``SemLock.__enter__`` just after the
    lock's own ``__enter__()`` returned, their ``__exit__`` before it releases,
    ``_AcquireFutures`` between two futures -- and leave the lock held by a thread that will not
    release it: the decoder's ``put``, a worker's ``set_result``, a band thread's
    ``numba.get_num_threads``, the clean-up's own ``get`` and the interpreter's exit (joining
    that band thread) then wait for it forever (the hang of ``video`` after two Ctrl-C at once,
    docs/reliability.md)."""
    if frame is None:
        return False
    module, name = frame.f_globals.get("__name__"), frame.f_code.co_name
    if (module, name) in _INTERRUPTIBLE:
        return False
    return module in LOCKING_MODULES or name in ("__enter__", "__exit__")


def _unwinding() -> bool:
    """The main thread is handling a :class:`Stopped` (an ``except`` or ``finally`` block, a
    context manager's exit on the way out): its clean-up -- closing the video, removing the
    temporary files, bounded by its own timeouts -- must not be cut short by a second signal
    (issue 34, item 13: a second Ctrl-C 0.02 s after the first left ``.o.partial.PID-TOKEN.mp4``
    and a decoder thread inside OpenCV, which aborted the process). A Stopped that was caught
    and swallowed (by a library) is no longer being handled: the next signal raises again."""
    return isinstance(sys.exc_info()[1], Stopped)


def _unraisable(hook: Callable[[Any], object]) -> Callable[[Any], object]:
    """``sys.unraisablehook`` while :func:`handled` runs: a :class:`Stopped` raised where Python
    cannot propagate it -- a ``__del__``, a ctypes callback (llvmlite's object-cache hook while
    Numba compiles), a weakref callback -- printed an "Exception ignored ... Stopped" block and
    was lost. It is dropped quietly and the signal is raised again a moment later, so it lands
    in the code that runs next; anything else goes to ``hook``."""

    def unraisable(info: Any) -> object:
        global _in_hook
        exc = getattr(info, "exc_value", None)
        if not (isinstance(exc, Stopped) and _active):
            return hook(info)
        _in_hook = True
        try:
            _raise_again(exc.signum)
        finally:
            _in_hook = False
        return None

    return unraisable


def _raise_again(signum: int) -> None:
    """``signum`` marked as arrived again in a moment (from a helper thread, as the C handler
    marks a signal: the handler then runs at the main thread's next bytecode -- not here, inside
    the hook, a ``__del__`` or locking code, :func:`_in_locking_code`), while this module's
    handler is still the one set. The helper is a bare ``_thread`` thread: starting a
    ``threading.Thread`` takes the ``threading`` module's own locks, which the main thread may
    hold where the handler interrupted it."""

    def later() -> None:
        time.sleep(0.005)
        if _active and signal.getsignal(signum) is _handler:
            _thread.interrupt_main(signum)

    _thread.start_new_thread(later, ())


def received() -> int | None:
    """The first stop signal received during :func:`handled` (``None``: none)."""
    return _received


def stop_requested() -> bool:
    """A stop signal came: a frame loop should finish its frame and leave."""
    return _received is not None


def check() -> None:
    """Raise :class:`Stopped` when a stop signal came (and was swallowed somewhere)."""
    if _received is not None:
        raise Stopped(_received)


@contextmanager
def deferred(repeats: bool = True, raise_on_exit: bool = True) -> Iterator[None]:
    """Within the block a (first) stop signal only sets :func:`stop_requested`; on leaving
    it, :class:`Stopped` is raised if one came (unless ``raise_on_exit`` is False: the caller
    reports the stop itself). ``repeats=False``: later signals are ignored as well (a
    clean-up that must finish; it is bounded by its own timeouts). Nestable; a no-op
    outside the main thread."""
    global _deferring, _patient
    _deferring += 1
    _patient += 0 if repeats else 1
    try:
        yield
    finally:
        _deferring -= 1
        _patient -= 0 if repeats else 1
    if raise_on_exit:
        check()


def wait(done: Callable[[], bool], timeout: float, step: float = 0.1) -> bool:
    """Poll ``done()`` every ``step`` seconds until it is true (``True``), ``timeout`` seconds
    pass or a stop signal came (``False``): a bounded wait that wakes on a stop."""
    end = time.monotonic() + timeout
    while not done():
        if stop_requested() or time.monotonic() >= end:
            return False
        time.sleep(min(step, max(end - time.monotonic(), 0.0)))
    return True


@contextmanager
def handled(after: str = "restore") -> Iterator[None]:
    """Run a command with the stop signals turned into :class:`Stopped` (see the module
    docstring). A signal that comes while the handlers are being set only sets the flag: the
    block should begin with :func:`check` inside its ``try``. When the block ends the signals
    are ignored until the handlers are reset (a stop after the command cannot interrupt the
    clean-up), then ``after="restore"`` restores the previous handlers and ``"ignore"`` leaves
    them ignored (the process is the command: ``python -m fastdet``)."""
    global _received, _deferring, _patient, _active, _put_off_since
    if threading.current_thread() is not threading.main_thread() or _active:
        yield  # another thread, or inside a handled() block already (a batch run by the CLI)
        return
    if after not in ("restore", "ignore"):
        raise ValueError(f"after must be 'restore' or 'ignore', got {after!r}")
    previous = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    _received, _deferring, _patient, _put_off_since = None, 1, 0, None  # held while the handlers are being set
    for s in STOP_SIGNALS:
        if previous[s] != signal.SIG_IGN:  # an ignored signal stays ignored (see the docstring)
            signal.signal(s, _handler)
    _active += 1
    hook = sys.unraisablehook
    sys.unraisablehook = _unraisable(hook)
    _deferring = 0
    try:
        yield
    finally:
        _deferring, _patient = _deferring + 1, _patient + 1  # from here on a signal changes nothing
        for s, h in previous.items():
            signal.signal(s, signal.SIG_IGN if after == "ignore" else h if h is not None else signal.SIG_DFL)
        sys.unraisablehook = hook
        _active -= 1
        _received, _deferring, _patient = None, 0, 0  # a stop belongs to the command it stopped
        _ignored.clear()
        _put_off_since = None


def reset() -> None:
    """Forget a received signal (tests)."""
    global _received
    _received = None

"""``python -m fastdet`` -> :func:`fastdet.cli.main.main`.

Stop signals (Ctrl-C, SIGTERM, SIGHUP) in the life of the process:

- from the package's first line (``fastdet/__init__.py``, which runpy and the console script
  import before this module) until the dispatcher's handlers are set: one line ``fastdet:
  interrupted (SIGINT) while starting`` and status 128 + the signal (nothing written yet);
- while the command runs: :mod:`fastdet.signals` (one line ``fastdet COMMAND: interrupted``);
  a signal while those handlers are being set is held and raised inside the command's ``try``;
- once the command's outcome is known: ignored until the process exits, so its status and its
  one line are the command's. When a helper thread was left blocked inside OpenCV
  (:mod:`fastdet.exiting`), the process ends at once with that status, without the
  interpreter's teardown (which would abort: "terminate called without an active exception").

A ``KeyboardInterrupt`` that still reaches :func:`run` (a handler of someone else's) is
reported as the same one line, never as a traceback.
"""
import os
import sys

from . import _catch_stops_while_starting


def run() -> int:
    """The console script's and ``python -m fastdet``'s entry point."""
    _catch_stops_while_starting()  # done on import when started as the command; a launcher's run
    try:
        from .cli.main import main

        status = main(stops_after="ignore")
        # the command is over (its outputs final, its line out): a signal from here on -- also
        # one while the interpreter shuts down -- cannot change its status
        import signal

        for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
            if s is not None:
                signal.signal(s, signal.SIG_IGN)
        from . import exiting

        if exiting.threads_left():  # a thread still inside OpenCV would abort the teardown
            exiting.exit_now(status)
        return status
    except KeyboardInterrupt as exc:
        import signal

        signum = int(getattr(exc, "signum", signal.SIGINT))  # a Stopped, or Python's own for SIGINT
        try:
            os.write(2, f"fastdet: interrupted ({signal.Signals(signum).name})\n".encode())
            atomic = sys.modules.get("fastdet.io.atomic")
            if atomic is not None:
                atomic.remove_partials()
        finally:
            os._exit(128 + signum)


if __name__ == "__main__":
    sys.exit(run())

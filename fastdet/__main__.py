"""``python -m fastdet`` -> :func:`fastdet.cli.main.main`.

A stop signal (Ctrl-C, SIGTERM, SIGHUP) that comes while the command's modules are still
being imported -- before the dispatcher installs its handlers -- ends the process with one
line and status 128 + the signal, not a ``KeyboardInterrupt`` traceback: nothing has been
written yet. Once the command has returned, stop signals are ignored until the process exits,
so its status is the command's.
"""
import os
import signal
import sys


def _early_stop(signum: int, frame: object) -> None:
    try:
        os.write(2, f"fastdet: interrupted ({signal.Signals(signum).name}) while starting\n".encode())
    finally:
        os._exit(128 + signum)


def run() -> int:
    """The console script's and ``python -m fastdet``'s entry point."""
    for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if s is not None and signal.getsignal(s) in (signal.default_int_handler, signal.SIG_DFL):
            signal.signal(s, _early_stop)
    from .cli.main import main

    status = main()
    # The command is over: its outputs are final and its status and line are out. A stop signal
    # from here on stops nothing, and one that came while the interpreter shuts down (after it
    # has put the default handlers back) would kill the process and hide that status.
    for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if s is not None:
            signal.signal(s, signal.SIG_IGN)
    return status


if __name__ == "__main__":
    sys.exit(run())

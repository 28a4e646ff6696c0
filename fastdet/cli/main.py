"""``python -m fastdet`` / ``fastdet``: one subcommand per job.

Each subcommand lives in its own module of this package, which provides
``add_arguments(parser)`` and ``run(args) -> int``; only the module of the command being run
is imported (so ``fastdet video`` does not pay for scikit-learn or Dask).

Errors: a :class:`~fastdet.errors.FastdetError` (bad input, a model that does not load, a
write that failed) becomes one line ``fastdet COMMAND: error: MESSAGE`` on stderr and exit
status 2. Anything else is a bug in fastdet and shows its traceback (exit 1). Ctrl-C,
SIGTERM and SIGHUP (:mod:`fastdet.signals`) print ``fastdet COMMAND: interrupted
(SIGTERM)`` and exit with 128 + the signal's number (130 for Ctrl-C), whatever exception
the interrupted code then raised. Standard output closed by its reader (``fastdet eval ... |
head -1``, ``| true``: ``EPIPE``) ends the command quietly with status 141 (128 + SIGPIPE, what
a shell shows for a program that a closed pipe stops, so ``set -o pipefail`` sees it); it can
only happen when the results are printed, after the output files are complete.
``FASTDET_DEBUG=1`` shows the traceback of user errors too.
An argument the command does not know is reported with the command's own usage.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from typing import Any

from .. import console
from .. import signals as _signals
from .._version import __version__
from ..errors import FastdetError

#: exit status when standard output was closed by its reader (128 + SIGPIPE)
EXIT_BROKEN_PIPE = 141

# name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "video": ("fastdet.cli.video", "detect vehicles in a video: annotated video, boxes file, JSON lines"),
    "image": ("fastdet.cli.image", "detect vehicles in one image and draw the boxes"),
    "train": ("fastdet.cli.train", "train a model on folders of 64x64 vehicle / non-vehicle crops"),
    "eval": ("fastdet.cli.eval", "score predicted boxes against MOTChallenge ground truth"),
    "mine-negatives": ("fastdet.cli.mine", "save the windows the detector wrongly fires on as hard negatives"),
    "bench": ("fastdet.cli.bench", "time the pipeline stages on a video or image"),
    "batch": ("fastdet.cli.batch", "many videos in parallel on Dask (local or a cluster): boxes, manifest, resume"),
    "label": ("fastdet.cli.label",
              "a teacher CNN (ONNX) boxes every N-th frame of videos: CLIP.teacher.txt + CLIP.frames"),
    "adapt": ("fastdet.cli.adapt",
              "fit a main model to one camera from its footage (a teacher CNN labels it): MYCAM.npz"),
    "warmup": ("fastdet.cli.warmup", "compile every numba kernel now (for images, CI and cluster workers)"),
}


class _HelpFormatter(argparse.HelpFormatter):
    """Every command's ``--help``: an option and its help on one line up to a 30-column option."""

    def __init__(self, prog: str) -> None:
        super().__init__(prog, max_help_position=32)


def _prog() -> str:
    """``fastdet`` when run as the console script, ``python -m fastdet`` otherwise."""
    argv0 = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    return "fastdet" if argv0 == "fastdet" else "python -m fastdet"


def _chosen(argv: Sequence[str]) -> str | None:
    """The subcommand named in ``argv`` (the first argument that is not an option)."""
    for a in argv:
        if not a.startswith("-"):
            return a if a in SUBCOMMANDS else None
    return None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The argument parser; only ``command``'s own arguments are added (every command's
    when ``command`` is None: slower, it imports all command modules)."""
    parser = argparse.ArgumentParser(
        prog=_prog(),
        description="fastdet: real-time HOG + linear-classifier vehicle detection for dashcam video.",
    )
    parser.add_argument("--version", action="version", version=f"fastdet {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (modname, help_) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_, formatter_class=_HelpFormatter)
        if command is None or name == command:
            mod = importlib.import_module(modname)
            mod.add_arguments(p)
            p.set_defaults(_module=mod, _name=name)
    return parser


def _say(line: str) -> None:
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):  # stderr gone (SIGHUP: the terminal closed)
        pass


def _interrupted(name: str, signum: int, detail: str = "") -> int:
    """One line for a command stopped by ``signum``; its exit status (128 + signum)."""
    stopped = _signals.Stopped(signum, detail)
    _say(f"fastdet {name}: interrupted ({stopped.name})" + (f"; {detail}" if detail else ""))
    return stopped.exit_status


def main(argv: Sequence[str] | None = None, stops_after: str = "restore") -> int:
    """Run the command ``argv`` names (default ``sys.argv[1:]``); its exit status. ``stops_after``:
    the stop signals' handlers once the command is over (:func:`fastdet.signals.handled`:
    ``"restore"`` the caller's, ``"ignore"`` when the process is the command)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    command = _chosen(argv)
    threads = os.environ.get("NUMBA_NUM_THREADS")
    if threads is not None and not (threads.strip().isdigit() and int(threads) >= 1):
        # Numba would raise a ValueError traceback while the command's modules are imported
        _say(f"fastdet{' ' + command if command else ''}: error: NUMBA_NUM_THREADS must be a whole number >= 1, "
             f"got {threads!r}")
        return 2
    parser = build_parser(command) if command is not None else build_parser("")
    args, extra = parser.parse_known_args(argv)
    if extra:
        # the command's own usage, not the top-level one
        sub = _subparser(parser, args.command)
        (sub or parser).error(f"unrecognized arguments: {' '.join(extra)}")
    if args.command is None:
        parser.print_help()
        return 0
    debug = os.environ.get("FASTDET_DEBUG", "") not in ("", "0")
    name = args._name
    console.set_prog(f"fastdet {name}")
    stdout = sys.stdout
    if stdout is not None:
        sys.stdout = _GuardedStdout(stdout)  # type: ignore[assignment]
    try:
        status = _dispatch(args, name, debug, stops_after)
        if status == EXIT_BROKEN_PIPE and stdout is not None and stdout is sys.__stdout__:
            _quiet_stdout(stdout)
        return status
    finally:
        if isinstance(sys.stdout, _GuardedStdout):
            try:
                sys.stdout.flush()
            except (OSError, StdoutError):
                pass
            sys.stdout = stdout


def _dispatch(args: argparse.Namespace, name: str, debug: bool, stops_after: str = "restore") -> int:
    """Run the command inside the stop-signal handlers (see the module docstring); the outcome
    is reported once they are reset, so a late signal cannot interrupt its one line."""
    signum: int | None = None
    detail = ""
    error: FastdetError | None = None
    status = 0
    try:
        with _signals.handled(stops_after):
            try:
                _signals.check()  # a signal while the handlers were being set
                status = int(args._module.run(args) or 0)
                _signals.check()  # swallowed by a library: still a stop
            except _signals.Stopped as exc:
                signum, detail = exc.signum, exc.detail
            except BrokenPipeError:
                # the reader of standard output is gone (`| head -1`, `| true`): nothing to
                # tell it; the results were being printed, the output files are complete
                status = EXIT_BROKEN_PIPE
            except FastdetError as exc:
                signum, error = _signals.received(), exc
            except BaseException:
                # an exception out of code that a signal interrupted (a compiler, a library)
                # is the signal's doing, not a bug: one line
                if _signals.received() is None or debug:
                    raise
                signum = _signals.received()
    except _signals.Stopped as exc:  # a first signal just as the outcome was being taken
        signum, detail = signum or exc.signum, detail or exc.detail
    if signum is not None:
        return _interrupted(name, signum, detail)
    if error is not None:
        if debug:
            raise error
        _say(f"fastdet {name}: error: {error}")
        return 2
    return status


def _quiet_stdout(stream: Any) -> None:
    """``stream``'s file descriptor pointed at ``/dev/null``: what is still buffered for the
    closed pipe does not fail again when the interpreter flushes it at exit."""
    try:
        fd = stream.fileno()
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, fd)
        finally:
            os.close(null)
    except (OSError, ValueError, AttributeError):
        pass


class StdoutError(FastdetError):
    """Standard output cannot be written (a full disk, a closed pipe)."""


class _GuardedStdout:
    """Standard output whose failed writes raise :class:`StdoutError` (one line, exit 2)
    instead of an ``OSError`` traceback; after a failure it writes to ``/dev/null``, so the
    interpreter's own flush at exit does not fail again."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def _fail(self, exc: OSError) -> StdoutError:
        try:
            self._stream = open(os.devnull, "w")  # noqa: SIM115 - lives until the process ends
        except OSError:
            pass
        return StdoutError(f"cannot write the results to standard output ({exc.strerror or exc}); "
                           f"the output files, if any, are complete")

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise self._fail(exc) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise self._fail(exc) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _subparser(parser: argparse.ArgumentParser, name: str | None) -> argparse.ArgumentParser | None:
    """The sub-parser of command ``name``."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and name in action.choices:
            return action.choices[name]
    return None

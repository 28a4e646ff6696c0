"""``python -m fastdet`` / ``fastdet``: one subcommand per job.

Each subcommand lives in its own module of this package, which provides
``add_arguments(parser)`` and ``run(args) -> int``; only the module of the command being run
is imported (so ``fastdet video`` does not pay for scikit-learn or Dask).

Errors: a :class:`~fastdet.errors.FastdetError` (bad input, a model that does not load, a
write that failed) becomes one line ``fastdet COMMAND: error: MESSAGE`` on stderr and exit
status 2. Anything else is a bug in fastdet and shows its traceback (exit 1). Ctrl-C prints
``fastdet COMMAND: interrupted`` and exits 130. ``FASTDET_DEBUG=1`` shows the traceback of
user errors too.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from .._version import __version__
from ..errors import FastdetError

# name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "video": ("fastdet.cli.video", "detect vehicles in a video: annotated video, boxes file, JSON lines"),
    "image": ("fastdet.cli.image", "detect vehicles in one image and draw the boxes"),
    "train": ("fastdet.cli.train", "train a model on folders of 64x64 vehicle / non-vehicle crops"),
    "eval": ("fastdet.cli.eval", "score predicted boxes against MOTChallenge ground truth"),
    "mine-negatives": ("fastdet.cli.mine", "save the windows the detector wrongly fires on as hard negatives"),
    "bench": ("fastdet.cli.bench", "time the pipeline stages on a video or image"),
    "batch": ("fastdet.cli.batch", "many videos in parallel on Dask (local or a cluster): boxes, manifest, resume"),
}


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
        p = sub.add_parser(name, help=help_, description=help_)
        if command is None or name == command:
            mod = importlib.import_module(modname)
            mod.add_arguments(p)
            p.set_defaults(_module=mod, _name=name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    command = _chosen(argv)
    parser = build_parser(command) if command is not None else build_parser("")
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    debug = os.environ.get("FASTDET_DEBUG", "") not in ("", "0")
    try:
        return int(args._module.run(args) or 0)
    except FastdetError as exc:
        if debug:
            raise
        print(f"fastdet {args._name}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"fastdet {args._name}: interrupted", file=sys.stderr)
        return 130

"""``python -m fastdet``: one subcommand per job.

Each subcommand lives in its own module, which provides ``add_arguments(parser)`` (cheap:
no heavy imports) and ``run(args) -> int``. A :class:`~fastdet.errors.FastdetError` (or an
``OSError``/``ValueError`` raised while reading user input) becomes one line on stderr and
exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from typing import Sequence

from ._version import __version__
from .errors import FastdetError

# name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "video": ("fastdet.video", "detect vehicles in a video: annotated video, boxes file, JSON lines"),
    "image": ("fastdet.imagecmd", "detect vehicles in one image and draw the boxes"),
    "train": ("fastdet.train", "train a model on folders of 64x64 vehicle / non-vehicle crops"),
    "eval": ("fastdet.eval", "score predicted boxes against MOTChallenge ground truth"),
    "mine-negatives": ("fastdet.mine", "save the windows the detector wrongly fires on as hard negatives"),
    "bench": ("fastdet.bench", "time the pipeline stages on a video or image"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m fastdet",
        description="fastdet: real-time HOG + linear-classifier vehicle detection for dashcam video.",
    )
    parser.add_argument("--version", action="version", version=f"fastdet {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (modname, help_) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_)
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as exc:
            if exc.name != modname:
                raise
            p.set_defaults(_module=None, _name=name)
            continue
        mod.add_arguments(p)
        p.set_defaults(_module=mod, _name=name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    if args._module is None:
        print(f"fastdet: '{args._name}' is not implemented in this version yet", file=sys.stderr)
        return 2
    try:
        return int(args._module.run(args) or 0)
    except FastdetError as exc:
        print(f"fastdet {args._name}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"fastdet {args._name}: interrupted", file=sys.stderr)
        return 130
    except (OSError, ValueError) as exc:  # user input we could not read
        print(f"fastdet {args._name}: error: {exc}", file=sys.stderr)
        return 2

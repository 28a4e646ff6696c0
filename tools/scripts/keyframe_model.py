"""Build a main model (64x64 windows) from the data set's crops plus crops cut from the annotated
frames of the clips in the data folder: every annotated vehicle (jittered, mirrored), random
background and the hard negatives the bundled model fires on there
(:func:`fastdet.train.keyframe_model.train_keyframe_model`). The data set's part is trained as
the bundled ``fastdet/models/default.npz`` is (docs/training.md): mirrored crops, truncated and
re-encoded copies, logistic regression.

Usage (from the repository root)::

    python -m tools.scripts.keyframe_model --out M.npz [--clips A,B,...] [--exclude A,B]
        [--data DIR] [--jitter N] [--background N] [--hard-per-frame N] [--hard-rounds N]
        [--near-per-frame N [--near-iou I]] [--max-aspect A] [--C C]
        [--max-per-folder N]

``--clips``: the clips to learn from (default: every annotated clip of the data folder,
:func:`fastdet.eval.clips.annotated_clips`); ``--exclude``: all but these (the
leave-one-clip-out models of ``tools/studies/model_loo.py``); ``--max-per-folder``: at most
this many data-set crops per folder (quick runs and tests only); ``--near-per-frame``: also up to
this many near misses a frame as hard negatives (windows the bundled model fires on that touch
a target at IoU below ``--near-iou``, :mod:`fastdet.train.keyframe_model`). About 3-4 minutes of CPU and
10 GB of memory with the whole data set.
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from fastdet.config import FeatureConfig
from fastdet.data import data_dir
from fastdet.errors import FastdetError
from fastdet.eval.clips import annotated_clips
from fastdet.model import Model
from fastdet.train.keyframe_model import KeyframeRecipe, train_keyframe_model
from fastdet.train.keyframes import read_annotated_frames

#: the data-set part's training options: those of the bundled main model (docs/training.md)
TRAINING = {"seed": 0, "truncate": 0.25, "truncate_keep": (0.75, 0.875), "reencode": 0.25, "C": 0.0218}


def choose_clips(data: Path, clips: str | None, exclude: str | None) -> list[str]:
    """The annotated clips of ``data`` named by ``clips`` (comma-separated; default all) minus
    ``exclude``; :class:`FastdetError` for a name that is not an annotated clip or when none is left."""
    known = [c.name for c in annotated_clips(data)]
    want = clips.split(",") if clips else known
    drop = exclude.split(",") if exclude else []
    unknown = sorted(set(want + drop) - set(known))
    if unknown:
        raise FastdetError(f"not annotated clips of {data}: {', '.join(unknown)} (there are {', '.join(known)})")
    left = [c for c in want if c not in drop]
    if not left:
        raise FastdetError("no clip left to learn from")
    return left


def build(out: Path, clips: list[str], data: Path, recipe: KeyframeRecipe = KeyframeRecipe(),
          C: float | None = None, max_per_folder: int | None = None, previous: Sequence[Model] = (),
          log=print) -> None:
    """Train the main model on the data set and the annotated frames of ``clips``; save it to
    ``out`` (``previous``: :func:`~fastdet.train.keyframe_model.train_keyframe_model`'s)."""
    frames = [f for c in clips for f in read_annotated_frames(data, c)]
    args: dict[str, Any] = dict(TRAINING, max_per_folder=max_per_folder)
    if C is not None:
        args["C"] = C
    model = train_keyframe_model(data, FeatureConfig(), frames, recipe, log=log, previous=previous, **args)
    d = KeyframeRecipe()
    opts = ["--clips", ",".join(clips)] + [f"--{k.replace('_', '-')} {v:g}" for k, v in asdict(recipe).items()
                                           if v != getattr(d, k)]
    model.metadata["training"]["command"] = "python -m tools.scripts.keyframe_model " + " ".join(
        opts + ([f"--C {C:g}"] if C is not None else []))
    model.save(out)
    log(f"wrote {out}")


def add_recipe_arguments(p: argparse.ArgumentParser) -> None:
    """The :class:`KeyframeRecipe` options (``--jitter``, ``--background``, ``--hard-per-frame``,
    ``--hard-rounds``, ``--max-aspect``), defaults from the recipe; also read by
    ``tools/studies/model_loo.py``."""
    d = KeyframeRecipe()
    p.add_argument("--jitter", type=int, default=d.jitter)
    p.add_argument("--background", type=int, default=d.background)
    p.add_argument("--hard-per-frame", type=int, default=d.hard_per_frame)
    p.add_argument("--hard-rounds", type=int, default=d.hard_rounds)
    p.add_argument("--near-per-frame", type=int, default=d.near_per_frame,
                   help="near misses per frame: windows touching a target at IoU below --near-iou (default: none)")
    p.add_argument("--near-iou", type=float, default=d.near_iou)
    p.add_argument("--max-aspect", type=float, default=d.max_aspect,
                   help="only targets narrower than this (width / height) are positives (default: all)")


def recipe_from_args(args: argparse.Namespace) -> KeyframeRecipe:
    """The recipe of :func:`add_recipe_arguments`' options."""
    return KeyframeRecipe(jitter=args.jitter, background=args.background, hard_per_frame=args.hard_per_frame,
                          hard_rounds=args.hard_rounds, max_aspect=args.max_aspect,
                          near_per_frame=args.near_per_frame, near_iou=args.near_iou)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--data", type=Path, default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    p.add_argument("--clips", help="comma-separated clips to learn from (default: every annotated clip)")
    p.add_argument("--exclude", help="comma-separated clips not to learn from")
    add_recipe_arguments(p)
    p.add_argument("--C", type=float, default=None, help=f"inverse regularisation (default {TRAINING['C']})")
    p.add_argument("--max-per-folder", type=int, default=None)
    args = p.parse_args(argv)
    data = args.data or data_dir()
    try:
        if args.out.suffix != ".npz":
            raise FastdetError(f"--out must end in .npz, got {args.out}")
        if args.C is not None and not args.C > 0:
            raise FastdetError(f"--C must be > 0, got {args.C}")
        if args.max_per_folder is not None and args.max_per_folder < 1:
            raise FastdetError(f"--max-per-folder must be >= 1, got {args.max_per_folder}")
        clips = choose_clips(data, args.clips, args.exclude)
        build(args.out, clips, data, recipe_from_args(args), args.C, args.max_per_folder)
    except (FastdetError, ValueError) as exc:
        print(f"keyframe_model: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Build the small-vehicle component (``fastdet/models/small.npz``): a 32x32-window linear model
trained on the data set's 64x64 crops shrunk to 32x32 (``cv2.INTER_AREA``) plus native-resolution
tiles of the crops as negatives (:func:`fastdet.train.small.train_small`). No frame of an
annotated clip is used, so every clip may score it.

Usage (from the repository root)::

    python -m tools.scripts.small_model [--out fastdet/models/small.npz] [--data DIR]
        [--tiles N] [--part-tiles N] [--C C] [--orientations N] [--window PX]

The bundled model is built with the defaults (about 2 minutes of CPU); the command that made a
model is in its metadata (``metadata["small"]["command"]``), with the recipe and the held-out
(sequence split) accuracy.
"""
from __future__ import annotations

import argparse
import shlex
import sys
from dataclasses import replace
from pathlib import Path

from fastdet.config.small import SMALL_FEATURES
from fastdet.data import data_dir
from fastdet.errors import FastdetError
from fastdet.train.small import SmallRecipe, train_small


def recipe_from_args(args: argparse.Namespace) -> SmallRecipe:
    """The :class:`SmallRecipe` the options ask for (the default recipe otherwise)."""
    r = SmallRecipe()
    feats = r.features
    if args.orientations is not None:
        feats = replace(feats, orientations=args.orientations)
    if args.window is not None:
        feats = replace(feats, window=args.window, spatial_size=args.window // (SMALL_FEATURES.window
                                                                                // SMALL_FEATURES.spatial_size))
    kw = {k: v for k, v in (("tiles", args.tiles), ("part_tiles", args.part_tiles), ("C", args.C)) if v is not None}
    return replace(r, features=feats, **kw)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=Path("fastdet/models/small.npz"))
    p.add_argument("--data", type=Path, default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    p.add_argument("--tiles", type=int, help="native-resolution tiles per non-vehicle crop (negatives)")
    p.add_argument("--part-tiles", type=int, help="native-resolution tiles per vehicle crop (negatives)")
    p.add_argument("--C", type=float, help="inverse regularisation of the logistic regression")
    p.add_argument("--orientations", type=int, help="HOG orientations")
    p.add_argument("--window", type=int, help="window side in pixels (a multiple of 8, at most 64)")
    args = p.parse_args(argv if argv is not None else sys.argv[1:])
    command = "python -m tools.scripts.small_model " + shlex.join(argv if argv is not None else sys.argv[1:])
    try:
        recipe = recipe_from_args(args)
        model = train_small(args.data or data_dir(), recipe, command=command.strip())
        model.save(args.out)
    except (FastdetError, ValueError) as exc:
        print(f"small_model: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

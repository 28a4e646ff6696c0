"""Build the side-view component (``fastdet/models/side.npz``): a 64x32-window linear model of
vehicles whose annotated boxes are at least 1.6 times as wide as tall, trained on crops cut
from the annotated frames of the clips in the data folder
(:func:`fastdet.train.components.train_component`, :data:`~fastdet.train.components.SIDE_RECIPE`).

Usage (from the repository root)::

    python -m tools.scripts.side_model [--out fastdet/models/side.npz] [--clips A,B,...]
        [--exclude CLIP] [--data DIR] [--jitter N] [--data-negatives N] [--hard-rounds N]

``--clips``: the clips to learn from (default: every annotated clip of the data folder,
:func:`fastdet.eval.clips.annotated_clips`); ``--exclude``: all but these (comma-separated; the
leave-one-clip-out models of ``tools/studies/components_loo.py``). The bundled model is built
with the defaults (all five clips; about 2 minutes of CPU).
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from fastdet.config import side_search
from fastdet.data import data_dir
from fastdet.errors import FastdetError
from fastdet.train.components import SIDE_RECIPE, train_component
from fastdet.train.keyframes import read_annotated_frames
from tools.scripts.keyframe_model import choose_clips


def build(out: Path, clips: list[str], data: Path, jitter: int | None = None, data_negatives: int | None = None,
          hard_rounds: int | None = None, log=print) -> None:
    """Train the side component on ``clips`` and save it to ``out``."""
    recipe = SIDE_RECIPE
    for name, v in (("jitter", jitter), ("data_negatives", data_negatives), ("hard_rounds", hard_rounds)):
        if v is not None:
            recipe = replace(recipe, **{name: v})
    frames = [f for c in clips for f in read_annotated_frames(data, c)]
    model = train_component(recipe, frames, data, side_search(), log=log)
    model.save(out)
    log(f"wrote {out}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=Path("fastdet/models/side.npz"))
    p.add_argument("--data", type=Path, default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    p.add_argument("--clips", help="comma-separated clips to learn from (default: every annotated clip)")
    p.add_argument("--exclude", help="learn from every annotated clip but these (comma-separated)")
    p.add_argument("--jitter", type=int)
    p.add_argument("--data-negatives", type=int)
    p.add_argument("--hard-rounds", type=int)
    args = p.parse_args(argv)
    data = args.data or data_dir()
    try:
        clips = choose_clips(data, args.clips, args.exclude)
        build(args.out, clips, data, args.jitter, args.data_negatives, args.hard_rounds)
    except (FastdetError, ValueError) as exc:
        print(f"side_model: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``python -m fastdet train``: train a model on folders of 64x64 vehicle / non-vehicle crops.

Features → StandardScaler → LinearSVC / LogisticRegression (:mod:`fastdet.train.fit`).

Reports accuracy, precision, recall, F1 and the confusion matrix on a random 80/20 split
and on a leak-free *sequence* split (every folder cut into contiguous time blocks, see
:mod:`fastdet.train.dataset`), then refits on all the data and writes the model. Hard negatives
(``--negatives``) and flip augmentation only ever join the *training* part of a split, so
the test figures stay comparable; so do the augmented copies (``--truncate``: crops cut by
the image border, padded as the detector pads a window over the frame edge; ``--reencode``:
compression artefacts; :mod:`fastdet.train.augment`).
Deterministic for a given ``--seed``.
"""
from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from .. import signals as _signals
from .._numba import ensure_compiled
from ..config import COLOR_SPACES, FeatureConfig
from ..data import data_dir
from ..errors import DataError, FastdetError
from ..features.window import KERNELS as FEATURE_KERNELS
from ..io.files import not_found
from ..io.paths import check_output
from ..train import augment
from ..train.augment import JPEG_QUALITY
from ..train.fit import train
from ._args import fraction, nonneg_int, positive_float, positive_int

#: upper bounds of the feature options (beyond them a 64x64 crop has no more to give, and
#: the feature vector would not fit in memory)
MAX_ORIENTATIONS = 64
MAX_HIST_BINS = 256


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.usage = "%(prog)s --out M.npz [--data DIR] [--negatives DIR]"
    io = p.add_argument_group("data and output")
    io.add_argument("--out", type=Path, required=True, metavar="M.npz", help="model file to write (.npz)")
    io.add_argument("--into-package", action="store_true",
                    help="allow --out inside the installed package")
    io.add_argument("--data", type=Path, default=None, metavar="DIR",
                    help="vehicles/ and non-vehicles/ crops ($FASTDET_DATA)")
    io.add_argument("--negatives", type=Path, action="append", default=[], metavar="DIR",
                    help="extra non-vehicle crops (repeatable)")
    io.add_argument("--positives", type=Path, action="append", default=[], metavar="DIR",
                    help="extra vehicle crops (repeatable)")
    io.add_argument("--frames", action="append", default=[], metavar="SPEC",
                    help="labelled pictures to learn from too, FORMAT:PATH[,opts] (repeatable; docs/labels.md)")
    io.add_argument("--max-per-folder", type=positive_int, default=None, metavar="N",
                    help="at most N crops a folder (quick runs)")
    io.add_argument("--no-refit", action="store_true", help="only the held-out figures: no model")
    io.add_argument("--no-progress", action="store_true", help="no progress bars")
    fit = p.add_argument_group("classifier")
    fit.add_argument("--classifier", choices=("linearsvc", "logreg"), default="logreg",
                     help="linear classifier (default logreg)")
    fit.add_argument("--C", type=positive_float, default=None, metavar="C", help="inverse regularisation, > 0")
    fit.add_argument("--split", choices=("both", "random", "sequence"), default="both",
                     help="held-out evaluations (default both)")
    fit.add_argument("--seed", type=int, default=0, metavar="N", help="random seed (default 0)")
    aug = p.add_argument_group("augmentation (training parts only)")
    aug.add_argument("--no-flip", action="store_true", help="no mirrored copies")
    aug.add_argument("--truncate", type=fraction, default=0.0, metavar="F",
                     help="truncated copies of this fraction (default 0)")
    aug.add_argument("--truncate-keep", type=fraction, nargs=2, metavar=("A", "B"),
                     default=[augment.MIN_KEEP, augment.MAX_KEEP],
                     help=f"columns a copy keeps (default {augment.MIN_KEEP:g} {augment.MAX_KEEP:g})")
    aug.add_argument("--truncate-vehicles-only", action="store_true",
                     help="no truncated non-vehicles")
    aug.add_argument("--reencode", type=fraction, default=0.0, metavar="F",
                     help="re-encoded copies of this fraction (default 0)")
    aug.add_argument("--jpeg-quality", type=int, nargs=2, metavar=("Q1", "Q2"), default=list(JPEG_QUALITY),
                     help=f"their JPEG quality (default {JPEG_QUALITY[0]} {JPEG_QUALITY[1]})")
    feat = p.add_argument_group("features")
    feat.add_argument("--color-space", choices=COLOR_SPACES, default=None, help="colour space")
    feat.add_argument("--orientations", type=positive_int, default=None, metavar="N", help="HOG orientation bins")
    feat.add_argument("--spatial-size", type=nonneg_int, default=None, metavar="N", help="spatial-bin side (0: none)")
    feat.add_argument("--hist-bins", type=nonneg_int, default=None, metavar="N", help="colour histogram bins (0: none)")
    feat.add_argument("--hog-channels", default=None, metavar="LIST", help="e.g. 0,1,2 or ALL")
    feat.add_argument("--window-rows", type=int, nargs=2, metavar=("A", "B"), default=None,
                      help="a wide-window model on rows [A, B)")


def _command_name() -> str:
    """How fastdet was started, for the model's record: ``fastdet`` or ``python -m fastdet``."""
    argv0 = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    return "fastdet" if argv0 == "fastdet" else "python -m fastdet"


def feature_config_from_args(args: argparse.Namespace) -> FeatureConfig:
    cfg = FeatureConfig()
    changes: dict[str, Any] = {}
    for flag, value, top in (("--orientations", args.orientations, MAX_ORIENTATIONS),
                             ("--spatial-size", args.spatial_size, cfg.window),
                             ("--hist-bins", args.hist_bins, MAX_HIST_BINS)):
        if value is not None and value > top:
            raise FastdetError(f"{flag} must be at most {top}, got {value}")
    if args.color_space:
        changes["color_space"] = args.color_space
    if args.orientations is not None:
        changes["orientations"] = args.orientations
    if args.spatial_size is not None:
        changes["spatial_size"] = args.spatial_size
    if args.hist_bins is not None:
        changes["hist_bins"] = args.hist_bins
    if args.window_rows:
        a, b = args.window_rows
        if not 0 <= a < b <= cfg.window:
            raise FastdetError(f"--window-rows must satisfy 0 <= A < B <= {cfg.window}, got {a} {b}")
        changes["window_height"] = b - a
    if args.hog_channels:
        hc = args.hog_channels
        try:
            changes["hog_channels"] = "ALL" if hc.upper() == "ALL" else tuple(int(c) for c in hc.split(","))
        except ValueError:
            raise FastdetError(f"--hog-channels must be channels such as 0,1,2 or ALL, got {hc!r}") from None
    try:
        return replace(cfg, **changes) if changes else cfg
    except ValueError as exc:
        raise FastdetError(f"feature options: {exc}") from None


def _check_inputs(data: Path, args: argparse.Namespace) -> None:
    """The data folders exist (before any of them is loaded)."""
    if data.exists() and not data.is_dir():
        raise DataError(f"--data {data}: is a file, expected a folder with vehicles/ and non-vehicles/")
    if not data.is_dir():
        raise not_found(data, f"data folder {data} not found (give --data or set FASTDET_DATA)")
    for sub in ("vehicles", "non-vehicles"):
        if not (data / sub).is_dir():
            raise DataError(f"data folder {data} has no {sub}/ folder")
    for flag, folders in (("--negatives", args.negatives), ("--positives", args.positives)):
        for f in folders:
            if f.exists() and not f.is_dir():
                raise DataError(f"{flag} {f}: is a file, expected a folder of crops")
            if not f.is_dir():
                raise DataError(f"{flag} {f}: folder not found")


def _read_frames(specs: list[str]) -> list:
    """Every picture of the ``--frames`` specs (:func:`fastdet.labels.sets.read_spec`): a set
    that does not read is one line (DataError) before any training."""
    if not specs:
        return []
    from ..labels.sets import read_spec

    pictures = []
    for spec in specs:
        got = read_spec(spec)
        if not got:
            raise DataError(f"--frames {spec}: no labelled picture in it")
        pictures += got
    return pictures


def run(args: argparse.Namespace) -> int:
    data = args.data or data_dir()
    out: Path = args.out
    if out.suffix != ".npz":
        raise FastdetError(f"--out must end in .npz, got {out}")
    config = feature_config_from_args(args)
    # everything checked before the data is loaded (minutes of work)
    if not args.no_refit:
        check_output(out, "model", "--out", into_package=args.into_package)
    _check_inputs(Path(data), args)
    q0, q1 = args.jpeg_quality
    k0, k1 = args.truncate_keep
    if not 0 < k0 <= k1 <= 1:
        raise FastdetError(f"--truncate-keep must satisfy 0 < A <= B <= 1, got {k0:g} {k1:g}")
    if not 1 <= q0 <= q1 <= 100:
        raise FastdetError(f"--jpeg-quality must satisfy 1 <= Q1 <= Q2 <= 100, got {q0} {q1}")
    pictures = _read_frames(args.frames)  # every set read (and checked) before the long work
    ensure_compiled(FEATURE_KERNELS, what="the feature kernels")
    progress = not args.no_progress and sys.stderr.isatty()
    extra = None
    if pictures:
        from ..model import load_model
        from ..train.pictures import PictureRecipe, picture_training_crops

        bundled = load_model()
        # hard negatives: the bundled model's false windows on complete pictures (its features only)
        extra = picture_training_crops(pictures, config, PictureRecipe(),
                                       bundled if bundled.config == config else None, progress)
    model, report = train(data, config, args.classifier, args.C, args.split, args.seed, args.negatives,
                          not args.no_flip, args.max_per_folder, not args.no_refit, progress,
                          window_top=args.window_rows[0] if args.window_rows else None,
                          positives=args.positives, truncate=args.truncate,
                          truncate_negatives=not args.truncate_vehicles_only, reencode=args.reencode,
                          jpeg_quality=(q0, q1), truncate_keep=(k0, k1),
                          extra_crops=extra)
    if model is not None:
        _signals.check()  # a stop that a library swallowed: no model
        model.metadata["training"]["command"] = f"{_command_name()} train " + " ".join(sys.argv[2:])
        model.save(out)
        print(f"wrote {out}")
    return 0

"""``python -m fastdet mine-negatives``: save the windows the detector wrongly fires on
(see :mod:`fastdet.train.mine` for the rules)."""
from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from tqdm import tqdm

from .. import signals as _signals
from ..detect import Detector
from ..detect.checks import check_frame
from ..errors import DataError, FastdetError, WriteError
from ..io.atomic import partial_name
from ..io.files import stat_error
from ..io.images import check_image, write_image
from ..io.motfiles import read_gt
from ..io.paths import check_output_folder, name_max
from ..io.reader import FrameReader, source_kind
from ..train.mine import hard_negatives
from ._args import nonneg_int, positive_int


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("video", type=str, help="video, image, or image sequence (e.g. test_images/test%%d.jpg) to mine")
    p.add_argument("--out", type=Path, required=True,
                   help="folder for the 64x64 PNG crops (created once the input has been opened)")
    p.add_argument("--x-range", type=int, nargs=2, metavar=("A", "B"), default=None,
                   help="only windows entirely within columns [A, B)")
    p.add_argument("--y-range", type=int, nargs=2, metavar=("A", "B"), default=None,
                   help="only windows entirely within rows [A, B)")
    p.add_argument("--gt", type=Path, default=None,
                   help="MOTChallenge ground truth: windows touching any annotated box are not negatives")
    p.add_argument("--margin", type=int, default=8, help="px added around each annotated box (default 8)")
    p.add_argument("--model", type=Path, default=None, help="main model file (default: the bundled model)")
    p.add_argument("--oncoming-model", dest="oncoming_model", type=Path, default=None,
                   help="oncoming-traffic (wide-window) model file, for --part oncoming")
    p.add_argument("--wide-model", dest="oncoming_model", type=Path, default=None,
                   help=argparse.SUPPRESS)  # --oncoming-model's former name
    p.add_argument("--part", choices=("main", "oncoming", "wide"), default="main", metavar="{main,oncoming}",
                   help="mine the windows of the main (square) model or of the oncoming-traffic (wide-window) "
                        "model")  # 'wide': oncoming's former name, still accepted
    p.add_argument("--threshold", type=float, default=None,
                   help="decision value a window needs to count as positive (default: the search's own); "
                        "lower it to mine near misses too")
    p.add_argument("--start", type=nonneg_int, default=0, help="first frame (0-based)")
    p.add_argument("--frames", type=positive_int, default=None, help="number of frames to mine")
    p.add_argument("--every", type=positive_int, default=1, help="mine every k-th frame")
    p.add_argument("--prefix", default=None, help="file name prefix (default: the video's name)")
    p.add_argument("--no-progress", action="store_true")


def _check_options(args: argparse.Namespace) -> None:
    """Numbers and names in their domain, before any work."""
    for flag, rng in (("--x-range", args.x_range), ("--y-range", args.y_range)):
        if rng is not None and not 0 <= rng[0] < rng[1]:
            raise FastdetError(f"{flag} A B needs 0 <= A < B, got {rng[0]} {rng[1]}")
    if args.margin < 0:
        raise FastdetError(f"--margin must be >= 0 px, got {args.margin}")
    if args.threshold is not None and not math.isfinite(args.threshold):
        raise FastdetError(f"--threshold must be a finite number, got {args.threshold}")
    if args.prefix is not None:
        if args.prefix in ("", ".", "..") or "/" in args.prefix or os.sep in args.prefix \
                or (os.altsep and os.altsep in args.prefix) or "\0" in args.prefix:
            raise FastdetError(f"--prefix must be a plain file name part (no folder), got {args.prefix!r}")


def run(args: argparse.Namespace) -> int:
    if args.x_range is None and args.y_range is None and args.gt is None:
        raise FastdetError("say where there are no vehicles: --x-range/--y-range and/or --gt")
    _check_options(args)
    if args.part == "wide":
        args.part = "oncoming"
    if args.part == "oncoming" and args.oncoming_model is None:
        raise FastdetError("--part oncoming needs --oncoming-model")
    if source_kind(args.video) == "file":
        try:
            os.stat(args.video)
        except OSError as exc:  # "file not found", "symlink loop"
            raise stat_error(args.video, exc) from None
    check_output_folder(args.out, "--out")
    gt = None
    if args.gt is not None:
        gt = read_gt(args.gt)
    # the main model's windows are mined (or the oncoming one's), never a side-view component's
    det = Detector(args.model, oncoming=args.oncoming_model, side=False)
    if args.threshold is not None:
        for sc in det.scorers:
            sc.search = replace(sc.search, threshold=args.threshold)
    win_cfg = det.config if args.part == "main" else det.oncoming_model.config
    if Path(args.video).is_file() and cv2.haveImageReader(args.video):
        check_image(args.video)  # a truncated JPEG: one line, before any output
    # the input is opened (and its first frame checked) before --out is created
    reader = FrameReader(args.video, args.start, args.frames)
    try:
        check_frame(det, reader.first_frame, str(args.video), more=reader.colour_sample)
        prefix = args.prefix or Path(args.video).stem.replace("%", "")
        _check_crop_names(args, prefix, reader)
        det.warmup()  # compiles on a first run, after saying so
        args.out.mkdir(parents=True, exist_ok=True)
        bar = None
        if not args.no_progress and sys.stderr.isatty():
            bar = tqdm(total=reader.expected, desc="mining", unit="frame")
        saved = done = 0
        written: list[Path] = []  # this run's crops: removed again if the run fails
        failed = True
        try:
            saved, done = _mine(args, det, reader, gt, win_cfg, prefix, bar, written)
            failed = False
        finally:
            if failed and not _signals.stop_requested():
                for p in written:
                    p.unlink(missing_ok=True)
        if bar:
            bar.close()
    finally:
        reader.close()
    print(f"mined {saved} false-positive windows from {done} frames into {args.out}")
    return 0


def _check_crop_names(args: argparse.Namespace, prefix: str, reader: FrameReader) -> None:
    """``DataError`` (one line, before ``--out`` is made) when the longest crop name this run
    can write -- its temporary name while written -- is longer than ``--out``'s file system
    takes (``NAME_MAX``: a 240-character video name or ``--prefix``)."""
    h, w = reader.shape[:2]
    last = reader.frame_count if reader.frame_count is not None else 2**31 - 1
    longest = crop_name(prefix, max(last, 99999), -w, -h, w, h)  # x1, y1 may lie off the frame
    size, limit = len(os.fsencode(partial_name(longest).name)), name_max(args.out)
    if size > limit:
        whose = f"--prefix {prefix[:40]}..." if args.prefix else f"{args.video} (the crops are named after it)"
        raise DataError(f"{whose}: crop names would be up to {size} bytes with the temporary name's "
                        f"{size - len(os.fsencode(longest))}, longer than the {limit} the file system of "
                        f"{args.out} takes; give a shorter --prefix")


def crop_name(prefix: str, frame_no: int, x1: int, y1: int, x2: int, y2: int) -> str:
    """A crop's file name: ``PREFIX_fFRAME_X1_Y1_W_H.png`` (unique for a window of a frame)."""
    return f"{prefix}_f{frame_no:05d}_{x1}_{y1}_{x2 - x1}_{y2 - y1}.png"


def _mine(args: argparse.Namespace, det: Detector, reader: FrameReader, gt: Any, win_cfg: Any, prefix: str,
          bar: Any, written: list[Path]) -> tuple[int, int]:
    """The frame loop: ``(crops saved, frames read)``; each new crop's path joins ``written``."""
    saved = done = 0
    for frame_no, frame, _ in reader:  # 1-based frame numbers, as in MOTChallenge files
        done += 1
        if bar:
            bar.update()
        if (done - 1) % args.every:
            continue
        gt_boxes = None
        if gt is not None:
            gb = gt.boxes[gt.frames == frame_no]
            gt_boxes = gb + np.array([-args.margin, -args.margin, args.margin, args.margin])
        seen: set[str] = set()
        for (x1, y1, x2, y2), crop in hard_negatives(det, frame, args.part, win_cfg, args.x_range,
                                                     args.y_range, gt_boxes):
            # the whole box names the crop (two windows may share x1, y1 and the width); the
            # same box twice (two search bands) is the same crop: written and counted once
            path = args.out / crop_name(prefix, frame_no, x1, y1, x2, y2)
            if path.name in seen:
                continue
            seen.add(path.name)
            new = not path.exists()  # a crop an earlier run wrote is not this run's to remove
            try:
                write_image(path, crop)
            except DataError:
                raise WriteError(f"{path}: could not write the crop (disk full or no permission?); "
                                 f"the crops this run wrote before it were removed") from None
            if new:
                written.append(path)
            saved += 1
    return saved, done

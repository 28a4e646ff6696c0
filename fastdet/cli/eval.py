"""``python -m fastdet eval``: score predicted boxes against MOTChallenge ground truth."""
from __future__ import annotations

import argparse
import json
import sys

from ..errors import FastdetError
from ..eval.metrics import evaluate
from ..eval.report import format_table, plot_pr
from ..io.motfiles import Predictions, read_gt, read_predictions
from ..io.reader import check_source
from ..video.run import iter_video_detections
from ._args import (
    add_horizon_argument,
    add_oncoming_arguments,
    add_refine_argument,
    add_search_argument,
    pipeline_config,
)

# ---------------------------------------------------------------------------------------
# CLI


def _iou_arg(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {s!r}") from None
    if not (0.0 < v <= 1.0):
        raise argparse.ArgumentTypeError(f"must be in (0, 1], got {s}")
    return v


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--gt", required=True, metavar="GT.txt",
                        help="MOTChallenge ground truth: frame,id,left,top,width,height,consider,class,visibility")
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--pred", metavar="PRED.txt",
                     help="predictions: MOTChallenge lines frame,id,left,top,width,height,conf,... "
                          "(or the JSON lines of `fastdet video`, *.jsonl)")
    src.add_argument("--video", metavar="CLIP.mp4",
                     help="run the default video pipeline on this clip and evaluate its boxes")
    parser.add_argument("--model", metavar="MODEL.npz", help="model for --video (default: the bundled one)")
    add_oncoming_arguments(parser)
    add_refine_argument(parser)
    add_horizon_argument(parser)
    add_search_argument(parser)
    track = parser.add_mutually_exclusive_group()
    track.add_argument("--no-track", action="store_true",
                       help="--video without the tracker (boxes without ids: no MOT metrics)")
    track.add_argument("--offline", action="store_true",
                       help="--video with the offline pass (gap interpolation, tracks extended back)")
    parser.add_argument("--iou", type=_iou_arg, default=0.5, help="IoU a match needs (default 0.5)")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    parser.add_argument("--plot", metavar="PR.png", help="write the precision-recall curve as a PNG")


def _video_predictions(args: argparse.Namespace) -> Predictions:
    check_source(args.video)
    frames = iter_video_detections(args.video, pipeline_config(args), progress=True,
                                   offline=getattr(args, "offline", False))
    return Predictions.from_frames(frames, source=args.video)


def run(args: argparse.Namespace) -> int:
    no_track, offline = getattr(args, "no_track", False), getattr(args, "offline", False)
    if args.video is None and (args.model is not None or args.oncoming_model is not None or args.no_oncoming
                               or no_track or offline or getattr(args, "no_refine", False)
                               or getattr(args, "traffic", "right") != "right"):
        raise FastdetError("--model, --oncoming-model, --no-oncoming, --traffic, --no-refine, --no-track and "
                           "--offline only apply with --video")
    gt = read_gt(args.gt)
    if args.video is not None:
        preds = _video_predictions(args)
    else:
        preds = read_predictions(args.pred)
    result = evaluate(gt, preds, iou=args.iou)
    if args.plot:
        plot_pr(result, args.plot)
    if args.json:
        out = {"gt": args.gt, ("video" if args.video else "pred"): args.video or args.pred, **result.to_dict()}
        if args.plot:
            out["plot"] = args.plot
        print(json.dumps(out, allow_nan=False))
    else:
        print(format_table(result))
        if args.plot:
            print(f"PR curve written to {args.plot}")
    sys.stdout.flush()
    return 0

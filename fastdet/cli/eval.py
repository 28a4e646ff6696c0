"""``python -m fastdet eval``: score predicted boxes against MOTChallenge ground truth; with
``--frames SPEC`` (repeatable) the single-picture search on labelled picture sets
(:mod:`fastdet.eval.pictures`: recall only where labels are partial); ``--all`` adds the data
folder's human-labelled picture sets (dawn_fog, dawn_weather, idd_mini, kitti_tiny) as rows
after the clips (not with ``--pred-dir``). With ``--video`` (and ``--all`` running the pipeline)
a video that ends before its ground truth's last frame (or keyframe) is scored on the frames
it gave, after one note "the video ended at frame N, before the ground truth's last frame M"
(:func:`decoded_only`): the frames never decoded say nothing about the detector."""
from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..console import note
from ..detections import Detections
from ..errors import DataError, FastdetError
from ..eval.clips import annotated_clips, markdown_table, report_json, score_clip
from ..eval.metrics import evaluate
from ..eval.report import format_table, plot_pr
from ..io.atomic import write_bytes
from ..io.keyframes import keyframes_for, keyframes_path, read_keyframes
from ..io.motfiles import read_gt, read_predictions
from ..io.paths import bundled_models, check_paths, is_inside
from ..io.reader import check_source
from ..video.detector import main_model_records, recorded_horizon
from ..video.run import iter_video_detections
from ._args import add_horizon_argument, pipeline_config, pipeline_groups

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
    parser.usage = ("%(prog)s --gt GT.txt (--pred P.txt | --video C.mp4)\n"
                    "       %(prog)s (--all | --frames FORMAT:PATH) [--out R.json]")
    what = parser.add_argument_group("what to score")
    what.add_argument("--gt", metavar="GT.txt", help="MOTChallenge ground truth")
    src = what.add_mutually_exclusive_group()
    src.add_argument("--pred", metavar="PRED.txt", help="predicted boxes (MOTChallenge or *.jsonl)")
    src.add_argument("--video", metavar="CLIP.mp4", help="run the video pipeline on this clip")
    what.add_argument("--keyframes", metavar="FILE",
                      help="score only these frames (default: CLIP.frames)")
    what.add_argument("--iou", type=_iou_arg, default=0.5, help="IoU a match needs (default 0.5)")
    what.add_argument("--json", action="store_true", help="print the result as one JSON object")
    what.add_argument("--plot", metavar="PR.png", help="write the precision-recall curve")
    every = parser.add_argument_group("every annotated clip")
    every.add_argument("--all", action="store_true", help="every annotated clip and picture set of the data folder")
    every.add_argument("--data", metavar="DIR", help="the data folder (default: $FASTDET_DATA)")
    every.add_argument("--clips", metavar="A,B", help="only these clips")
    every.add_argument("--pred-dir", metavar="DIR", help="read DIR/CLIP.txt instead of running")
    every.add_argument("--out", metavar="REPORT.json", help="also write the report as JSON")
    every.add_argument("--frames", metavar="SPEC", action="append", default=[],
                       help="a labelled picture set FORMAT:PATH[,opts] (repeatable)")
    search, tracking, _ = pipeline_groups(parser)
    add_horizon_argument(search)
    track = tracking.add_mutually_exclusive_group()
    track.add_argument("--no-track", action="store_true", help="no tracker (no MOT metrics)")
    track.add_argument("--offline", action="store_true", help="with the offline pass (gaps filled)")


def _video_predictions(video: str, args: argparse.Namespace) -> tuple[Detections, int]:
    """The pipeline's boxes of every frame of ``video`` and the last frame number decoded."""
    check_source(video)
    frames = iter_video_detections(video, pipeline_config(args), progress=True, offline=getattr(args, "offline", False))
    seen = [0]

    def counted() -> Iterator[tuple[int, Detections]]:
        for fno, d in frames:
            seen[0] = max(seen[0], fno)
            yield fno, d

    return Detections.from_frames(counted(), source=video), seen[0]


def decoded_only(video: str, gt: Detections, keyframes: np.ndarray | None,
                 last: int) -> tuple[Detections, np.ndarray | None]:
    """Ground truth and keyframes cut to the frames the video gave (``1..last``), with one note
    when the video ended before the ground truth's last frame: those frames were never seen,
    so they are not scored (as misses they would only say the file is short). ``DataError``
    when no keyframe is left."""
    gt_last = int(gt.frames.max()) if len(gt) else 0
    if keyframes is not None:
        gt_last = max(gt_last, int(keyframes.max()))
    if last >= gt_last:
        return gt, keyframes
    note(f"{video}: the video ended at frame {last}, before the ground truth's last frame {gt_last}; "
         f"only frames 1-{last} are scored")
    gt = gt[gt.frames <= last]
    if keyframes is not None:
        keyframes = keyframes[keyframes <= last]
        if keyframes.size == 0:
            raise DataError(f"{video}: the video ended at frame {last}, before the first keyframe: nothing to score")
    return gt, keyframes


def _frame_rows(video: str | Path) -> int:
    """A video's height in pixels (from its header)."""
    import cv2

    cap = cv2.VideoCapture(str(video))
    try:
        rows = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)) if cap.isOpened() else 0
    finally:
        cap.release()
    if rows <= 0:
        raise DataError(f"{video}: cannot read the frame size")
    return rows


def _clip_predictions(pred_dir: str, name: str) -> Detections:
    for ext in (".txt", ".jsonl"):
        p = Path(pred_dir) / f"{name}{ext}"
        if p.is_file():
            return read_predictions(p)
    raise DataError(f"{pred_dir}: no predictions for clip {name} ({name}.txt or {name}.jsonl)")


#: the human-labelled picture sets of the data folder that ``--all`` scores
PICTURE_SETS = ("dawn_fog", "dawn_weather", "idd_mini", "kitti_tiny")


def _picture_sets(args: argparse.Namespace, shared: bool) -> list[tuple[str, list]]:
    """``(name, pictures)`` of every ``--frames`` spec, then (``shared``) the data folder's
    human-labelled picture sets; DataError (one line) for a spec that does not read."""
    from ..labels.sets import parse_spec, shared_sets

    out = []
    for spec in args.frames:
        fs = parse_spec(spec)
        pics = fs.read()
        label = fs.path.parent.name if fs.path.is_file() else fs.path.name
        out.append((f"{fs.format}:{label or fs.path}", pics))
    if shared:
        from ..data import data_dir

        sets = shared_sets(args.data or data_dir())
        out += [(name, sets[name]) for name in PICTURE_SETS if name in sets]
    return out


def _score_picture_sets(sets: list[tuple[str, list]], args: argparse.Namespace) -> list:
    """Each set scored with the single-picture search (:func:`fastdet.detect_picture`)."""
    from ..config.picture import FIRST_STAGE_ONLY
    from ..eval.pictures import score_pictures
    from ..video.picture import PictureDetector
    from ..video.run import progress_bar

    det = PictureDetector(args.model, FIRST_STAGE_ONLY if getattr(args, "no_refine", False) else None)
    from .._numba import ensure_compiled

    ensure_compiled(det.kernels)
    scores = []
    for name, pics in sets:
        bar = progress_bar(len(pics), not getattr(args, "no_progress", False), name)
        try:
            scores.append(score_pictures(name, pics, det.detect, iou=args.iou, each=lambda _: bar.update(1)))
        finally:
            bar.close()
    return scores


def _run_frames(args: argparse.Namespace) -> int:
    """``eval --frames SPEC ...`` without ``--all``: the picture sets only."""
    from ..eval.clips import markdown_table, report_json
    from ..labels.sets import parse_spec

    specs = [parse_spec(spec).path for spec in args.frames]
    check_paths([("--model", args.model), *bundled_models(), *[("--frames", p) for p in specs]],
                [("--out", args.out, "report")])
    for p in specs:  # a labelled set's folder is read whole
        if args.out is not None and p.is_dir() and is_inside(args.out, p):
            raise DataError(f"--out {args.out}: is inside {p}, which --frames reads; write the report elsewhere")
    scores = _score_picture_sets(_picture_sets(args, shared=False), args)
    report = report_json([], {"iou": args.iou, "model": args.model or "bundled", "search": "picture"}, scores)
    text = json.dumps(report, indent=1, allow_nan=False) + "\n"
    if args.out is not None:
        write_bytes(args.out, text.encode())
    print(text, end="") if args.json else print(markdown_table([], scores))
    sys.stdout.flush()
    return 0


def _data_folder_inputs(root: Path) -> list[tuple[str, Path]]:
    """The data folder's files that ``eval --all`` reads besides the clips' own (the picture
    sets read every ground truth, keyframe list and teacher file): ``(label, path)`` inputs."""
    return [("the data folder's", p) for sub in ("annotations", "teacher") for p in sorted((root / sub).glob("*"))
            if p.is_file()]


def _check_report_path(out: str, root: Path, clips: list, picture_sets: bool) -> None:
    """``DataError`` for a ``--out`` that a later ``eval --all`` would read: a clip's keyframe
    list even where the clip has none yet (the report would make it sparsely annotated), or
    a file inside a picture-set folder (``frames/SET``, read whole)."""
    for c in clips:
        kf = keyframes_path(c.gt_path)
        if os.path.realpath(out) == os.path.realpath(kf):
            raise DataError(f"--out {out}: is the keyframe list of clip {c.name} ({kf}), which eval reads; "
                            f"give the report another name")
    if picture_sets:
        for name in PICTURE_SETS:
            folder = root / "frames" / name
            if folder.is_dir() and is_inside(out, folder):
                raise DataError(f"--out {out}: is inside the picture set {folder}, which eval reads; "
                                f"write the report elsewhere")


def _run_all(args: argparse.Namespace) -> int:
    if args.gt is not None or args.pred is not None or args.video is not None or args.keyframes is not None \
            or args.plot is not None:
        raise FastdetError("--all scores every annotated clip: "
                           "it takes no --gt, --pred, --video, --keyframes or --plot")
    if args.pred_dir is not None and (args.model is not None or args.oncoming_model is not None or args.no_oncoming
                                      or args.no_track or args.offline or getattr(args, "no_refine", False)
                                      or getattr(args, "traffic", "right") != "right"):
        raise FastdetError("--model, --oncoming-model, --no-oncoming, "
                           "--traffic, --no-refine, --no-track and --offline only apply when --all "
                           "runs the pipeline (not with --pred-dir)")
    clips = annotated_clips(args.data)
    if args.clips is not None:
        want = [c.strip() for c in args.clips.split(",") if c.strip()]
        unknown = sorted(set(want) - {c.name for c in clips})
        if unknown or not want:
            have = ", ".join(c.name for c in clips) or "none"
            raise FastdetError(f"--clips: no annotated clip named {', '.join(unknown) or '(empty)'} (have: {have})")
        clips = [c for c in clips if c.name in want]
    if not clips:
        from ..data import data_dir

        raise DataError(f"{args.data or data_dir()}: no annotated clips (annotations/CLIP.gt.txt with videos/CLIP.mp4)")
    preds_in = [("--pred-dir", Path(args.pred_dir) / f"{c.name}{ext}") for c in clips for ext in (".txt", ".jsonl")
                ] if args.pred_dir is not None else []
    root = Path(args.data) if args.data is not None else None
    if root is None:
        from ..data import data_dir

        root = data_dir()
    data_in = _data_folder_inputs(root) if args.pred_dir is None else []
    check_paths([("--model", args.model), ("--oncoming-model", args.oncoming_model), *bundled_models(),
                 *[(f"clip {c.name}", p) for c in clips for p in (c.video, c.gt_path, keyframes_path(c.gt_path))],
                 *preds_in, *data_in],
                [("--out", args.out, "report")])
    if args.out is not None:
        _check_report_path(args.out, root, clips, args.pred_dir is None)
    picture_sets = _picture_sets(args, shared=True) if args.pred_dir is None else []
    scores = []
    for clip in clips:
        gt, kf = clip.gt(), clip.keyframes()
        if args.pred_dir is not None:
            preds = _clip_predictions(args.pred_dir, clip.name)
        else:
            preds, last = _video_predictions(str(clip.video), args)
            gt, kf = decoded_only(str(clip.video), gt, kf, last)
        scores.append(score_clip(clip.name, gt, preds, _frame_rows(clip.video), kf, iou=args.iou))
    settings = {"iou": args.iou}
    if args.pred_dir is not None:
        settings["pred_dir"] = args.pred_dir
    else:
        config = pipeline_config(args)
        settings.update(model=args.model or "bundled", oncoming=args.oncoming_model or not args.no_oncoming,
                        traffic=config.traffic, refine=config.refine is not None, track=config.tracker is not None,
                        offline=args.offline, horizon=recorded_horizon(config.horizon, main_model_records(config)),
                        full_search=config.guided is None,
                        split=config.split is not None)
    pictures = _score_picture_sets(picture_sets, args) if picture_sets else []
    report = report_json(scores, settings, pictures)
    text = json.dumps(report, indent=1, allow_nan=False) + "\n"
    if args.out is not None:
        write_bytes(args.out, text.encode())
    if args.json:
        print(text, end="")
    else:
        print(markdown_table(scores, pictures))
        if args.out is not None:
            print(f"report written to {args.out}")
    sys.stdout.flush()
    return 0


def run(args: argparse.Namespace) -> int:
    if getattr(args, "all", False):
        return _run_all(args)
    if getattr(args, "frames", None):
        if args.gt is not None or args.pred is not None or args.video is not None or args.pred_dir is not None:
            raise FastdetError("--frames scores labelled pictures: it takes no --gt, --pred, --video or --pred-dir")
        return _run_frames(args)
    if getattr(args, "pred_dir", None) is not None or getattr(args, "out", None) is not None \
            or getattr(args, "clips", None) is not None or getattr(args, "data", None) is not None:
        raise FastdetError("--data, --clips, --pred-dir and --out only apply with --all")
    if args.gt is None or (args.pred is None and args.video is None):
        raise FastdetError("give --gt GT.txt and one of --pred PRED.txt or --video CLIP.mp4 (or --all)")
    no_track, offline = getattr(args, "no_track", False), getattr(args, "offline", False)
    if args.video is None and (args.model is not None or args.oncoming_model is not None or args.no_oncoming
                               or no_track or offline or getattr(args, "no_refine", False)
                               or getattr(args, "traffic", "right") != "right"):
        raise FastdetError("--model, --oncoming-model, --no-oncoming, "
                           "--traffic, --no-refine, --no-track and --offline only apply with --video")
    check_paths([("--gt", args.gt), ("--pred", args.pred), ("--video", args.video), ("--model", args.model),
                 ("--oncoming-model", getattr(args, "oncoming_model", None)),
                 ("--keyframes", getattr(args, "keyframes", None) or keyframes_path(args.gt)),
                 *(bundled_models() if args.video is not None else [])],
                [("--plot", args.plot, "PNG")])
    if args.video is not None:
        check_source(args.video)
    gt = read_gt(args.gt)
    kf_file = getattr(args, "keyframes", None)
    keyframes = read_keyframes(kf_file) if kf_file is not None else keyframes_for(args.gt)
    if args.video is not None:
        preds, last = _video_predictions(args.video, args)
        gt, keyframes = decoded_only(args.video, gt, keyframes, last)
    else:
        preds = read_predictions(args.pred)
    result = evaluate(gt, preds, iou=args.iou, keyframes=keyframes)
    if args.plot:
        plot_pr(result, args.plot)
    if args.json:
        out = {"gt": args.gt, ("video" if args.video else "pred"): args.video or args.pred, **result.to_dict()}
        if keyframes is not None:
            out["keyframes_file"] = str(kf_file if kf_file is not None else keyframes_path(args.gt))
        if args.plot:
            out["plot"] = args.plot
        print(json.dumps(out, allow_nan=False))
    else:
        print(format_table(result))
        if args.plot:
            print(f"PR curve written to {args.plot}")
    sys.stdout.flush()
    return 0

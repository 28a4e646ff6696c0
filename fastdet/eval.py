"""Score predicted boxes against MOTChallenge ground truth: precision, recall, F1, AP, MOT metrics.

Library::

    from fastdet.eval import evaluate, format_table
    from fastdet.motio import read_gt, read_predictions
    result = evaluate(read_gt("clip.gt.txt"), read_predictions("pred.txt"), iou=0.5)
    print(format_table(result)); result.to_dict()

CLI (``python -m fastdet eval``)::

    python -m fastdet eval --gt GT.txt (--pred PRED.txt | --video CLIP.mp4)
                           [--iou 0.5] [--json] [--plot PR.png] [--model MODEL.npz]

Definitions
-----------
Boxes are ``x1, y1, x2, y2`` with ``x2 = left + width`` (continuous coordinates);
``IoU = inter / (area_a + area_b - inter)``.

Frames. The evaluated frames are ``1 .. F`` where ``F`` is the last frame that has any
ground-truth line (target or ignore region), or ``num_frames`` if given. A frame inside that
range with no ground-truth line is a frame without vehicles: its predictions are false
positives. Predictions on frames after ``F`` are not evaluated (we do not know what is
there); they are counted in ``num_outside`` and the table says so.

Matching, per frame. Ground-truth boxes with ``consider = 1`` are targets, those with
``consider = 0`` are ignore regions. Predictions are taken by descending confidence (ties in
file order); each takes, among the targets not matched yet, the one with the highest IoU,
provided that IoU >= the threshold (ties: the first in file order): a true positive.
A prediction left unmatched is *dropped* (neither TP nor FP) when its intersection with one
single ignore region is at least half of the prediction's own area (and that area is > 0);
otherwise it is a false positive. Unmatched targets are false negatives.

Numbers. ``precision = TP / (TP + FP)``, ``recall = TP / targets``,
``F1 = 2 TP / (2 TP + FP + FN)``, ``fp_per_frame = FP / frames``; a ratio whose
denominator is 0 is NaN (``null`` in JSON, ``n/a`` in the table).
AP ranks all non-dropped predictions of all frames by confidence (descending, ties in frame
then file order, a stable sort), computes precision and recall after each rank (recall
normalised by the number of targets), takes the monotone precision envelope
(``p_interp(r) = max precision at recall >= r``) and sums the area under it over the recall
steps: PASCAL VOC's "all-point" AP (VOC 2010+). No predictions gives AP 0; no targets NaN.

MOT metrics. When some prediction carries a track id (not all ``-1``), MOTA, MOTP, IDF1 and
the number of id switches are computed with py-motmetrics: one ``MOTAccumulator`` update
per evaluated frame with the targets' ids, the ids of the predictions that are not dropped
by the ignore rule above (dropped ones are removed before motmetrics sees them), and the
distance ``1 - IoU``, set to "no match possible" (NaN) where IoU < the threshold (so the
maximum distance is ``1 - iou``). motmetrics matches with the Hungarian method and keeps
last frame's matches when still valid, so its TP/FP counts can differ slightly from the
greedy detection counts above. ``motp`` is motmetrics' MOTP: the mean ``1 - IoU`` of the
matched pairs (0 is perfect; the CLEAR-MOT overlap form is ``1 - motp``). In a file that
mixes ids and ``-1``, each ``-1`` box is given an identity of its own (an untracked box is a
new track). A track id used twice in one frame (targets or predictions) is an error.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ._cliargs import add_oncoming_arguments, oncoming_arg
from .errors import DataError, FastdetError
from .motio import GroundTruth, Predictions, read_gt, read_predictions

__all__ = [
    "EvalResult", "evaluate", "format_table", "plot_pr", "box_iou", "box_intersection",
    "match_frame", "average_precision", "precision_envelope", "add_arguments", "run",
]


# ---------------------------------------------------------------------------------------
# geometry and matching


def box_intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, M)`` intersection areas of x1, y1, x2, y2 boxes ``a (N, 4)`` and ``b (M, 4)``."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    return np.clip(w, 0.0, None) * np.clip(h, 0.0, None)


def _area(b: np.ndarray) -> np.ndarray:
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    return np.clip(b[:, 2] - b[:, 0], 0.0, None) * np.clip(b[:, 3] - b[:, 1], 0.0, None)


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(N, M)`` IoU of x1, y1, x2, y2 boxes (0 where both areas are 0)."""
    inter = box_intersection(a, b)
    union = _area(a)[:, None] + _area(b)[None, :] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        iou = np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)
    return iou


def match_frame(
    pred_boxes: np.ndarray,
    pred_scores: np.ndarray,
    gt_boxes: np.ndarray,
    ignore_boxes: np.ndarray | None = None,
    iou: float = 0.5,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Match one frame's predictions to its targets (see the module docstring).

    Returns ``(tp, dropped, gt_index)``, each ``(N,)`` over the predictions in input order:
    ``tp`` True for a true positive, ``dropped`` True for a prediction on an ignore region,
    ``gt_index`` the matched target's row (``-1`` if none). FP = ``~tp & ~dropped``.
    """
    pred_boxes = np.asarray(pred_boxes, dtype=np.float64).reshape(-1, 4)
    gt_boxes = np.asarray(gt_boxes, dtype=np.float64).reshape(-1, 4)
    n = pred_boxes.shape[0]
    tp = np.zeros(n, bool)
    gt_index = np.full(n, -1, np.int64)
    if n and gt_boxes.shape[0]:
        order = np.argsort(-np.asarray(pred_scores, dtype=np.float64).reshape(-1), kind="stable")
        ious = box_iou(pred_boxes, gt_boxes)
        taken = np.zeros(gt_boxes.shape[0], bool)
        for p in order:
            row = np.where(taken, -1.0, ious[p])
            j = int(np.argmax(row))
            if row[j] >= iou:
                taken[j] = True
                tp[p] = True
                gt_index[p] = j
    dropped = np.zeros(n, bool)
    if ignore_boxes is not None and n:
        ignore_boxes = np.asarray(ignore_boxes, dtype=np.float64).reshape(-1, 4)
        if ignore_boxes.shape[0]:
            inter = box_intersection(pred_boxes, ignore_boxes).max(axis=1)
            area = _area(pred_boxes)
            dropped = ~tp & (area > 0) & (inter >= 0.5 * area)
    return tp, dropped, gt_index


def precision_envelope(precision: np.ndarray) -> np.ndarray:
    """Monotone envelope: at each rank, the highest precision at this rank or later."""
    p = np.asarray(precision, dtype=np.float64)
    return np.maximum.accumulate(p[::-1])[::-1] if p.size else p.copy()


def average_precision(tp_ranked: np.ndarray, num_gt: int) -> tuple[float, np.ndarray, np.ndarray]:
    """VOC all-point AP of predictions already in ranking order.

    ``tp_ranked``: ``(N,)`` bool, True where the prediction at that rank is a true positive.
    Returns ``(ap, recall, precision)`` with ``recall``/``precision`` after each rank.
    """
    tp = np.asarray(tp_ranked, dtype=bool).reshape(-1)
    ctp = np.cumsum(tp, dtype=np.float64)
    cfp = np.cumsum(~tp, dtype=np.float64)
    precision = ctp / np.maximum(ctp + cfp, 1.0)
    if num_gt <= 0:
        return math.nan, np.full(tp.shape, math.nan), precision
    recall = ctp / float(num_gt)
    if tp.size == 0:
        return 0.0, recall, precision
    steps = np.diff(np.concatenate([[0.0], recall]))
    ap = float(np.sum(steps * precision_envelope(precision)))
    return ap, recall, precision


# ---------------------------------------------------------------------------------------
# result


def _ratio(num: float, den: float) -> float:
    return float(num) / float(den) if den > 0 else math.nan


@dataclass(frozen=True, eq=False)
class EvalResult:
    """Everything :func:`evaluate` found. Counts are over the evaluated frames.

    num_gt: targets (``consider = 1`` boxes); num_ignore: ignore regions.
    num_pred: predictions on evaluated frames (including dropped ones); num_dropped: those
    dropped on ignore regions; num_outside: predictions on frames after the last GT frame.
    pr_scores / pr_recall / pr_precision: ``(K,)`` arrays over the ranked non-dropped
    predictions (K = TP + FP): the confidence and the precision/recall after each rank.
    mota, motp, idf1, id_switches: None unless the predictions carry track ids.
    """

    iou_threshold: float
    frames: int
    num_gt: int
    num_ignore: int
    num_pred: int
    num_dropped: int
    num_outside: int
    tp: int
    fp: int
    fn: int
    precision: float
    recall: float
    f1: float
    fp_per_frame: float
    ap: float
    pr_scores: np.ndarray
    pr_recall: np.ndarray
    pr_precision: np.ndarray
    mota: float | None = None
    motp: float | None = None
    idf1: float | None = None
    id_switches: int | None = None

    @property
    def has_tracking(self) -> bool:
        return self.mota is not None

    def to_dict(self, curve: bool = False) -> dict[str, Any]:
        """Plain JSON-ready dict (NaN -> None). ``curve=True`` adds the PR arrays as lists."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray):
                if curve:
                    out[f.name] = [None if not math.isfinite(x) else float(x) for x in v.tolist()]
                continue
            if f.name in ("mota", "motp", "idf1", "id_switches") and not self.has_tracking:
                continue
            if isinstance(v, float) and not math.isfinite(v):
                v = None
            out[f.name] = v
        return out


# ---------------------------------------------------------------------------------------
# evaluation


def _frame_groups(frames: np.ndarray) -> dict[int, np.ndarray]:
    """frame number -> row indices (in file order) of the rows on that frame."""
    if frames.size == 0:
        return {}
    order = np.argsort(frames, kind="stable")
    cuts = np.flatnonzero(np.diff(frames[order])) + 1
    return {int(frames[idx[0]]): idx for idx in np.split(order, cuts)}


def evaluate(
    gt: GroundTruth,
    preds: Predictions,
    iou: float = 0.5,
    num_frames: int | None = None,
    tracking: bool | None = None,
) -> EvalResult:
    """Score ``preds`` against ``gt`` at IoU threshold ``iou`` (see the module docstring).

    num_frames: evaluate frames ``1..num_frames`` (default: the last GT frame).
    tracking: compute MOT metrics; default when the predictions carry ids.
    """
    if not (0.0 < iou <= 1.0):
        raise ValueError(f"iou threshold must be in (0, 1], got {iou}")
    F = gt.num_frames if num_frames is None else int(num_frames)
    if F < 0:
        raise ValueError(f"num_frames must be >= 0, got {num_frames}")

    g_in = gt.frames <= F
    p_in = preds.frames <= F
    num_outside = int((~p_in).sum())
    g_groups = _frame_groups(np.where(g_in, gt.frames, 0))
    p_groups = _frame_groups(np.where(p_in, preds.frames, 0))
    g_groups.pop(0, None)
    p_groups.pop(0, None)

    n = len(preds)
    tp = np.zeros(n, bool)
    dropped = np.zeros(n, bool)
    for f, pidx in p_groups.items():
        gidx = g_groups.get(f, np.zeros(0, np.int64))
        cons = gt.consider[gidx]
        t, d, _ = match_frame(
            preds.boxes[pidx], preds.scores[pidx], gt.boxes[gidx[cons]], gt.boxes[gidx[~cons]], iou
        )
        tp[pidx] = t
        dropped[pidx] = d

    evaluated = p_in & ~dropped
    num_gt = int((gt.consider & g_in).sum())
    num_ignore = int((~gt.consider & g_in).sum())
    n_tp = int(tp.sum())
    n_fp = int((evaluated & ~tp).sum())
    n_fn = num_gt - n_tp

    # global ranking: stable sort by descending score over (frame, file order)
    kept = np.flatnonzero(evaluated)
    kept = kept[np.lexsort((kept, preds.frames[kept]))]
    kept = kept[np.argsort(-preds.scores[kept], kind="stable")]
    ap, rec, prec = average_precision(tp[kept], num_gt)

    mot: dict[str, Any] = {}
    if tracking is None:
        tracking = preds.has_ids
    if tracking:
        mot = _mot_metrics(gt, preds, g_groups, p_groups, dropped, iou, F)

    return EvalResult(
        iou_threshold=float(iou),
        frames=F,
        num_gt=num_gt,
        num_ignore=num_ignore,
        num_pred=int(p_in.sum()),
        num_dropped=int(dropped.sum()),
        num_outside=num_outside,
        tp=n_tp,
        fp=n_fp,
        fn=n_fn,
        precision=_ratio(n_tp, n_tp + n_fp),
        recall=_ratio(n_tp, num_gt),
        f1=_ratio(2 * n_tp, 2 * n_tp + n_fp + n_fn),
        fp_per_frame=_ratio(n_fp, F),
        ap=ap,
        pr_scores=preds.scores[kept].copy(),
        pr_recall=rec,
        pr_precision=prec,
        **mot,
    )


def _check_unique(ids: np.ndarray, what: str, source: str, frame: int) -> None:
    if ids.size and np.unique(ids).size != ids.size:
        vals, counts = np.unique(ids, return_counts=True)
        raise DataError(f"{source}: {what} id {int(vals[counts > 1][0])} appears twice in frame {frame}")


def _mot_metrics(
    gt: GroundTruth,
    preds: Predictions,
    g_groups: dict[int, np.ndarray],
    p_groups: dict[int, np.ndarray],
    dropped: np.ndarray,
    iou: float,
    F: int,
) -> dict[str, Any]:
    try:
        import warnings

        import motmetrics as mm
    except ImportError as exc:  # pragma: no cover - it is a dependency
        raise FastdetError(f"MOT metrics need the motmetrics package ({exc})") from None

    pids = preds.ids.copy()
    untracked = np.flatnonzero(pids == -1)
    if untracked.size:  # each untracked box is a track of its own
        start = int(max(pids.max(initial=-1), -1)) + 1
        pids[untracked] = start + np.arange(untracked.size)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        acc = mm.MOTAccumulator(auto_id=False)
        empty = np.zeros(0, np.int64)
        for f in range(1, F + 1):
            gidx = g_groups.get(f, empty)
            gidx = gidx[gt.consider[gidx]]
            pidx = p_groups.get(f, empty)
            pidx = pidx[~dropped[pidx]]
            oids, hids = gt.ids[gidx], pids[pidx]
            _check_unique(oids, "ground-truth", gt.source, f)
            _check_unique(hids, "prediction", preds.source, f)
            ious = box_iou(gt.boxes[gidx], preds.boxes[pidx])
            dist = np.where(ious >= iou, 1.0 - ious, np.nan)
            acc.update(oids.tolist(), hids.tolist(), dist, frameid=f)
        mh = mm.metrics.create()
        summary = mh.compute(acc, metrics=["mota", "motp", "idf1", "num_switches", "num_objects"], name="all")
    row = summary.loc["all"]
    num_objects = int(row["num_objects"])

    def fin(x: Any) -> float:
        x = float(x)
        return x if math.isfinite(x) else math.nan

    return {
        "mota": fin(row["mota"]) if num_objects > 0 else math.nan,
        "motp": fin(row["motp"]),
        "idf1": fin(row["idf1"]),
        "id_switches": int(row["num_switches"]),
    }


# ---------------------------------------------------------------------------------------
# output


def _num(x: float | None, digits: int = 4) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{x:.{digits}f}"


def format_table(result: EvalResult) -> str:
    """A small human-readable table of the result (no trailing newline)."""
    r = result
    rows: list[tuple[str, str]] = [
        ("IoU threshold", f"{r.iou_threshold:g}"),
        ("frames", str(r.frames)),
        ("GT boxes", f"{r.num_gt}  (+ {r.num_ignore} ignore regions)"),
        ("predictions", f"{r.num_pred}  ({r.num_dropped} dropped on ignore regions)"),
        ("TP", str(r.tp)),
        ("FP", str(r.fp)),
        ("FN", str(r.fn)),
        ("precision", _num(r.precision)),
        ("recall", _num(r.recall)),
        ("F1", _num(r.f1)),
        ("FP per frame", _num(r.fp_per_frame, 3)),
        ("AP", _num(r.ap)),
    ]
    if r.has_tracking:
        rows += [
            ("MOTA", _num(r.mota)),
            ("MOTP (1 - IoU)", _num(r.motp)),
            ("IDF1", _num(r.idf1)),
            ("ID switches", str(r.id_switches)),
        ]
    width = max(len(k) for k, _ in rows)
    lines = [f"{k:<{width}}  {v}" for k, v in rows]
    if r.num_outside:
        lines.append(f"({r.num_outside} predictions after the last GT frame {r.frames} were not evaluated)")
    return "\n".join(lines)


def _pr_image(result: EvalResult, title: str | None = None) -> np.ndarray:
    import cv2

    W, H = 720, 560
    left, right, top, bottom = 90, 30, 60, 75
    pw, ph = W - left - right, H - top - bottom
    img = np.full((H, W, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    black, grey, blue, light = (0, 0, 0), (225, 225, 225), (180, 90, 20), (235, 190, 150)

    def px(r: float, p: float) -> tuple[int, int]:
        return int(round(left + r * pw)), int(round(top + (1.0 - p) * ph))

    def text_centered(s: str, cx: int, y: int, scale: float, thick: int = 1) -> None:
        (tw, _), _ = cv2.getTextSize(s, font, scale, thick)
        cv2.putText(img, s, (int(cx - tw / 2), y), font, scale, black, thick, cv2.LINE_AA)

    for k in range(11):  # grid and ticks every 0.1, labels every 0.2
        v = k / 10
        x, _ = px(v, 0)
        _, y = px(0, v)
        cv2.line(img, (x, top), (x, top + ph), grey, 1)
        cv2.line(img, (left, y), (left + pw, y), grey, 1)
        cv2.line(img, (x, top + ph), (x, top + ph + 6), black, 1)
        cv2.line(img, (left - 6, y), (left, y), black, 1)
        if k % 2 == 0:
            text_centered(f"{v:.1f}", x, top + ph + 24, 0.5)
            s = f"{v:.1f}"
            (tw, th), _ = cv2.getTextSize(s, font, 0.5, 1)
            cv2.putText(img, s, (left - 10 - tw, y + th // 2), font, 0.5, black, 1, cv2.LINE_AA)
    cv2.rectangle(img, (left, top), (left + pw, top + ph), black, 1)
    text_centered("recall", left + pw // 2, H - 22, 0.65)
    # rotated y label
    (tw, th), base = cv2.getTextSize("precision", font, 0.65, 1)
    lab = np.full((th + base + 4, tw + 4, 3), 255, np.uint8)
    cv2.putText(lab, "precision", (2, th + 2), font, 0.65, black, 1, cv2.LINE_AA)
    lab = cv2.rotate(lab, cv2.ROTATE_90_COUNTERCLOCKWISE)
    y0 = top + ph // 2 - lab.shape[0] // 2
    img[y0:y0 + lab.shape[0], 14:14 + lab.shape[1]] = lab

    if title is None:
        title = f"Precision-recall, IoU >= {result.iou_threshold:g}:  AP = {_num(result.ap, 3)}"
    text_centered(title, W // 2, 36, 0.65, 2)

    rec, prec = result.pr_recall, result.pr_precision
    if rec.size and np.all(np.isfinite(rec)):
        raw = np.array([px(r, p) for r, p in zip(rec, prec)], np.int32)
        cv2.polylines(img, [raw.reshape(-1, 1, 2)], False, light, 1, cv2.LINE_AA)
        env = precision_envelope(prec)
        pts = [px(0.0, env[0])]
        prev = 0.0
        for r, p in zip(rec, env):
            pts.append(px(prev, p))
            pts.append(px(r, p))
            prev = r
        pts.append(px(prev, 0.0))
        cv2.polylines(img, [np.array(pts, np.int32).reshape(-1, 1, 2)], False, blue, 2, cv2.LINE_AA)
        # legend
        lx, ly = left + pw - 230, top + 20
        cv2.line(img, (lx, ly), (lx + 30, ly), blue, 2, cv2.LINE_AA)
        cv2.putText(img, "interpolated (AP area)", (lx + 38, ly + 5), font, 0.45, black, 1, cv2.LINE_AA)
        cv2.line(img, (lx, ly + 20), (lx + 30, ly + 20), light, 1, cv2.LINE_AA)
        cv2.putText(img, "raw", (lx + 38, ly + 25), font, 0.45, black, 1, cv2.LINE_AA)
    else:
        text_centered("no predictions" if rec.size == 0 else "no ground-truth targets",
                      left + pw // 2, top + ph // 2, 0.7)
    return img


def plot_pr(result: EvalResult, path: str | os.PathLike[str], title: str | None = None) -> None:
    """Write the PR curve as a PNG (to a temporary name beside ``path``, then renamed)."""
    import cv2

    path = os.fspath(path)
    ok, buf = cv2.imencode(".png", _pr_image(result, title))
    if not ok:  # pragma: no cover
        raise FastdetError(f"{path}: PNG encoding failed")
    d = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=".pr-", suffix=".png.tmp", dir=d)
    except OSError as exc:
        raise DataError(f"{path}: cannot write ({exc.strerror or exc})") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(buf.tobytes())
        os.replace(tmp, path)
    except OSError as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise DataError(f"{path}: cannot write ({exc.strerror or exc})") from None


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
    parser.add_argument("--iou", type=_iou_arg, default=0.5, help="IoU a match needs (default 0.5)")
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    parser.add_argument("--plot", metavar="PR.png", help="write the precision-recall curve as a PNG")


def _video_predictions(video: str, model: str | None, oncoming: Any = True) -> Predictions:
    try:
        from .video import iter_video_detections
    except ImportError as exc:
        raise FastdetError(f"video pipeline not available ({exc})") from None
    if not os.path.isfile(video):
        raise DataError(f"{video}: file not found")
    return Predictions.from_frames(iter_video_detections(video, model=model, progress=True, oncoming=oncoming),
                                   source=video)


def run(args: argparse.Namespace) -> int:
    if args.video is None and (args.model is not None or args.oncoming_model is not None or args.no_oncoming):
        raise FastdetError("--model, --oncoming-model and --no-oncoming only apply with --video")
    gt = read_gt(args.gt)
    if args.video is not None:
        preds = _video_predictions(args.video, args.model, oncoming_arg(args))
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

"""Score predicted boxes against MOTChallenge ground truth: precision, recall, F1, AP, MOT metrics.

Library::

    from fastdet.eval import evaluate, format_table
    from fastdet.io.motfiles import read_gt, read_predictions
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

Keyframes. A sparsely annotated clip gives ``keyframes``, the frames that were annotated
(:mod:`fastdet.io.keyframes`). Then the evaluated frames are exactly those: a keyframe
without ground-truth lines has no vehicle, a prediction on any other frame is counted in
``num_outside`` and nowhere else (neither hit nor false alarm), ``frames`` is the number of
keyframes, and the MOT metrics see the keyframes only, in order (an id switch is counted
at keyframe granularity). Ground truth on a frame that is not a keyframe is an error.

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

MOT metrics. When some prediction carries a track id (not all ``-1``), MOTA, MOTP, IDF1,
the number of id switches and of fragmentations (a target's track interrupted: tracked,
then missed, then tracked again) are computed with py-motmetrics: one ``MOTAccumulator`` update
per evaluated frame with the targets' ids, the ids of the predictions that are not dropped
by the ignore rule above (dropped ones are removed before motmetrics sees them), and the
distance ``1 - IoU``, set to "no match possible" (NaN) where IoU < the threshold (so the
maximum distance is ``1 - iou``). motmetrics matches with the Hungarian method and keeps
last frame's matches when still valid, so its TP/FP counts can differ slightly from the
greedy detection counts above. ``motp`` is motmetrics' MOTP: the mean ``1 - IoU`` of the
matched pairs (0 is perfect; the CLEAR-MOT overlap form is ``1 - motp``). In a file that
mixes ids and ``-1``, each ``-1`` box is given an identity of its own (an untracked box is a
new track). A track id used twice in one frame (targets or predictions) is an error.
The distances are computed here (:func:`fastdet.boxes.iou`), not with motmetrics'
``iou_matrix``, which calls ``np.asfarray`` (removed in NumPy 2).
HOTA, DetA and AssA (:mod:`fastdet.eval.hota`, Luiten et al., IJCV 2021) are computed on
the same targets and predictions (ignore-region predictions removed the same way), over
the localisation thresholds 0.05..0.95 (they do not use ``iou``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ..boxes import iou as box_iou
from ..detections import Detections
from ..errors import DataError, FastdetError
from .hota import hota
from .matching import average_precision, match_frame, precision_envelope

__all__ = [
    "EvalResult", "evaluate", "frame_counts", "match_frame", "average_precision", "precision_envelope",
]


# ---------------------------------------------------------------------------------------
# result

_TRACKING_FIELDS = ("mota", "motp", "idf1", "id_switches", "fragmentations", "hota", "deta", "assa")


def _ratio(num: float, den: float) -> float:
    return float(num) / float(den) if den > 0 else math.nan


@dataclass(frozen=True, eq=False)
class EvalResult:
    """Everything :func:`evaluate` found. Counts are over the evaluated frames.

    num_gt: targets (``consider = 1`` boxes); num_ignore: ignore regions.
    num_pred: predictions on evaluated frames (including dropped ones); num_dropped: those
    dropped on ignore regions; num_outside: predictions on frames not evaluated (after the
    last GT frame, or not a keyframe). keyframes: True when only listed keyframes were
    evaluated (``frames`` is then their number).
    pr_scores / pr_recall / pr_precision: ``(K,)`` arrays over the ranked non-dropped
    predictions (K = TP + FP): the confidence and the precision/recall after each rank.
    mota, motp, idf1, id_switches, fragmentations, hota, deta, assa: None unless the
    predictions carry track ids (module docstring, "MOT metrics").
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
    fragmentations: int | None = None
    hota: float | None = None
    deta: float | None = None
    assa: float | None = None
    keyframes: bool = False

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
            if f.name in _TRACKING_FIELDS and not self.has_tracking:
                continue
            if isinstance(v, float) and not math.isfinite(v):
                v = None
            out[f.name] = v
        return out


# ---------------------------------------------------------------------------------------
# evaluation


#: memory budgets of :func:`evaluate` (a file controls them: refused in one line above them).
#: Boxes of ground truth x predictions on one frame: every frame's IoU matrix (and the
#: Hungarian matching's cost matrix) is that many float64 values (2**24: 4,096 x 4,096 boxes,
#: 128 MB a matrix)
MAX_FRAME_PAIRS = 2**24
#: ground-truth ids + predicted ids (each untracked box an id) of the MOT metrics: motmetrics'
#: IDF1 assigns them globally with a dense square matrix of that side (6,000: 288 MB)
MAX_TRACK_IDS = 6000


def _check_budget(gt: Detections, preds: Detections, g_groups: dict[int, np.ndarray],
                  p_groups: dict[int, np.ndarray], tracking: bool) -> None:
    """:class:`DataError` (one line, before any matching) when a frame holds more box pairs
    than :data:`MAX_FRAME_PAIRS` or the MOT metrics would see more ids than :data:`MAX_TRACK_IDS`."""
    for f, pidx in p_groups.items():
        gidx = g_groups.get(f)
        if gidx is not None and len(gidx) * len(pidx) > MAX_FRAME_PAIRS:
            raise DataError(f"{preds.source}: frame {f} holds {len(gidx)} ground-truth and {len(pidx)} predicted "
                            f"boxes: more than the {MAX_FRAME_PAIRS} pairs a frame may have (about "
                            f"{int(MAX_FRAME_PAIRS ** 0.5)} x {int(MAX_FRAME_PAIRS ** 0.5)} boxes; "
                            f"docs/reliability.md)")
    if tracking:
        rows = np.concatenate(list(p_groups.values())) if p_groups else np.zeros(0, np.int64)
        pids = preds.ids[rows] if preds.ids is not None else np.full(len(rows), -1)
        grows = np.concatenate(list(g_groups.values())) if g_groups else np.zeros(0, np.int64)
        n_ids = (np.unique(gt.ids[grows]).size if gt.ids is not None else 0) \
            + np.unique(pids[pids != -1]).size + int((pids == -1).sum())
        if n_ids > MAX_TRACK_IDS:
            raise DataError(f"{preds.source}: the MOT metrics would match {n_ids} ground-truth and predicted ids "
                            f"(each untracked box is an id): more than the {MAX_TRACK_IDS} they may have "
                            f"(docs/reliability.md); score fewer frames (--keyframes) or split the file")


def _frame_groups(frames: np.ndarray) -> dict[int, np.ndarray]:
    """frame number -> row indices (in file order) of the rows on that frame."""
    if frames.size == 0:
        return {}
    order = np.argsort(frames, kind="stable")
    cuts = np.flatnonzero(np.diff(frames[order])) + 1
    return {int(frames[idx[0]]): idx for idx in np.split(order, cuts)}


def _check_tables(gt: Detections, preds: Detections) -> None:
    """``ValueError`` unless ``gt`` has a ``frames`` column and ``preds`` ``frames`` and ``scores``
    (tables of a clip: :func:`fastdet.io.motfiles.read_gt`, :meth:`Detections.from_frames
    <fastdet.detections.Detections.from_frames>`)."""
    for table, what, need in ((gt, "ground truth", ("frames",)), (preds, "predictions", ("frames", "scores"))):
        missing = [c for c in need if getattr(table, c) is None]
        if missing:
            raise ValueError(f"{what} ({table.source}): a table of a clip needs {' and '.join(missing)}")


def _on_keyframes(gt: Detections, preds: Detections, scored: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(g_in, p_in)``: the rows of ``gt`` and ``preds`` on the frames ``scored``;
    :class:`DataError` for ground truth on another frame (a keyframe file that does not list
    every labelled frame)."""
    g_in = np.isin(gt.frames, scored)
    if not g_in.all():
        f = int(gt.frames[~g_in][0])
        raise DataError(f"{gt.source}: ground truth on frame {f}, which is not one of the keyframes")
    return g_in, np.isin(preds.frames, scored)


def _scored_groups(gt: Detections, preds: Detections, g_in: np.ndarray, p_in: np.ndarray
                   ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """frame number -> row indices of ``gt`` and of ``preds`` (:func:`_frame_groups`), of the rows
    ``g_in`` / ``p_in`` only."""
    g_groups = _frame_groups(np.where(g_in, gt.frames, 0))
    p_groups = _frame_groups(np.where(p_in, preds.frames, 0))
    g_groups.pop(0, None)
    p_groups.pop(0, None)
    return g_groups, p_groups


def _match(gt: Detections, preds: Detections, g_groups: dict[int, np.ndarray], p_groups: dict[int, np.ndarray],
           iou: float) -> tuple[np.ndarray, np.ndarray]:
    """``(tp, dropped)``, ``(N,) bool`` over the rows of ``preds``: each frame of ``p_groups``
    matched against its ground truth (:func:`~fastdet.eval.matching.match_frame`: targets and
    ignore regions by ``gt.targets``); rows on no frame of ``p_groups`` are neither."""
    consider = gt.targets
    tp = np.zeros(len(preds), bool)
    dropped = np.zeros(len(preds), bool)
    for f, pidx in p_groups.items():
        gidx = g_groups.get(f, np.zeros(0, np.int64))
        cons = consider[gidx]
        t, d, _ = match_frame(
            preds.boxes[pidx], preds.scores[pidx], gt.boxes[gidx[cons]], gt.boxes[gidx[~cons]], iou
        )
        tp[pidx] = t
        dropped[pidx] = d
    return tp, dropped


def frame_counts(gt: Detections, preds: Detections, keyframes: np.ndarray, iou: float = 0.5) -> np.ndarray:
    """``(K, 3) int64``: the ``(tp, fp, fn)`` of each of the ``K`` frames of ``keyframes`` (frame
    numbers, unique, in the order given), matched as :func:`evaluate` matches (IoU ``iou``, a
    prediction on an ignore region dropped); row ``k`` is what ``evaluate`` counts for that one
    keyframe. For a standard error over the frames (the operating point of ``fastdet adapt``)
    in one pass instead of one :func:`evaluate` a frame. Ground truth on a frame not listed:
    :class:`DataError`, as ``evaluate``."""
    if not (0.0 < iou <= 1.0):
        raise ValueError(f"iou threshold must be in (0, 1], got {iou}")
    _check_tables(gt, preds)
    frames = np.asarray(keyframes, dtype=np.int64).reshape(-1)
    if np.unique(frames).size != frames.size or (frames.size and frames.min() < 1):
        raise ValueError("keyframes must be unique frame numbers >= 1")
    g_groups, p_groups = _scored_groups(gt, preds, *_on_keyframes(gt, preds, frames))
    _check_budget(gt, preds, g_groups, p_groups, False)
    tp, dropped = _match(gt, preds, g_groups, p_groups, iou)
    row = {int(f): k for k, f in enumerate(frames)}
    out = np.zeros((frames.size, 3), np.int64)
    targets = gt.targets
    for f, gidx in g_groups.items():
        out[row[f], 2] = int(targets[gidx].sum())
    for f, pidx in p_groups.items():
        k = row[f]
        out[k, 0] = int(tp[pidx].sum())
        out[k, 1] = int((~tp[pidx] & ~dropped[pidx]).sum())
    out[:, 2] -= out[:, 0]
    return out


def evaluate(
    gt: Detections,
    preds: Detections,
    iou: float = 0.5,
    num_frames: int | None = None,
    tracking: bool | None = None,
    keyframes: np.ndarray | None = None,
) -> EvalResult:
    """Score ``preds`` against ``gt`` at IoU threshold ``iou`` (see the module docstring).

    gt: the ground truth of a clip (``frames``, ``ids``, ``boxes``, ``consider``; no
        ``consider`` column: every box is a target).
    preds: the predictions of the clip (``frames``, ``boxes``, ``scores``, ``ids``: -1 or no
        column for untracked boxes).
    num_frames: evaluate frames ``1..num_frames`` (default: the last GT frame).
    tracking: compute MOT metrics; default when the predictions carry ids.
    keyframes: ``(K,)`` frame numbers: evaluate those frames only (module docstring,
    "Keyframes"; not together with ``num_frames``).
    """
    if not (0.0 < iou <= 1.0):
        raise ValueError(f"iou threshold must be in (0, 1], got {iou}")
    _check_tables(gt, preds)
    consider = gt.targets
    if keyframes is not None:
        if num_frames is not None:
            raise ValueError("give num_frames or keyframes, not both")
        scored = np.unique(np.asarray(keyframes, dtype=np.int64).reshape(-1))
        if scored.size == 0 or scored[0] < 1:
            raise ValueError("keyframes must be frame numbers >= 1, at least one")
        g_in, p_in = _on_keyframes(gt, preds, scored)
        F = int(scored.size)
    else:
        F = gt.num_frames if num_frames is None else int(num_frames)
        if F < 0:
            raise ValueError(f"num_frames must be >= 0, got {num_frames}")
        g_in = gt.frames <= F
        p_in = preds.frames <= F
    num_outside = int((~p_in).sum())
    g_groups, p_groups = _scored_groups(gt, preds, g_in, p_in)
    if tracking is None:
        tracking = preds.has_ids
    _check_budget(gt, preds, g_groups, p_groups, bool(tracking))

    tp, dropped = _match(gt, preds, g_groups, p_groups, iou)

    evaluated = p_in & ~dropped
    num_gt = int((consider & g_in).sum())
    num_ignore = int((~consider & g_in).sum())
    n_tp = int(tp.sum())
    n_fp = int((evaluated & ~tp).sum())
    n_fn = num_gt - n_tp

    # global ranking: stable sort by descending score over (frame, file order)
    kept = np.flatnonzero(evaluated)
    kept = kept[np.lexsort((kept, preds.frames[kept]))]
    kept = kept[np.argsort(-preds.scores[kept], kind="stable")]
    ap, rec, prec = average_precision(tp[kept], num_gt)

    mot: dict[str, Any] = {}
    if tracking:
        # a scored frame with no box adds nothing to any of these metrics: only the frames
        # with boxes are visited (time and memory follow the files, not the largest frame number)
        visit = np.array(sorted(set(g_groups) | set(p_groups)), dtype=np.int64)
        mot = _mot_metrics(gt, preds, g_groups, p_groups, dropped, iou, visit)

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
        keyframes=keyframes is not None,
        **mot,
    )


def _check_unique(ids: np.ndarray, what: str, source: str, frame: int) -> None:
    if ids.size and np.unique(ids).size != ids.size:
        vals, counts = np.unique(ids, return_counts=True)
        raise DataError(f"{source}: {what} id {int(vals[counts > 1][0])} appears twice in frame {frame}")


def _mot_metrics(
    gt: Detections,
    preds: Detections,
    g_groups: dict[int, np.ndarray],
    p_groups: dict[int, np.ndarray],
    dropped: np.ndarray,
    iou: float,
    scored: np.ndarray,
) -> dict[str, Any]:
    try:
        import warnings

        import motmetrics as mm
    except ImportError as exc:  # pragma: no cover - it is a dependency
        raise FastdetError(f"MOT metrics need the motmetrics package ({exc})") from None

    if gt.ids is None:
        raise ValueError(f"ground truth ({gt.source}): MOT metrics need its ids")
    pids = preds.ids.copy() if preds.ids is not None else np.full(len(preds), -1, np.int64)
    untracked = np.flatnonzero(pids == -1)
    if untracked.size:  # each untracked box is a track of its own
        start = int(max(pids.max(initial=-1), -1)) + 1
        pids[untracked] = start + np.arange(untracked.size)

    per_frame = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        acc = mm.MOTAccumulator(auto_id=False)
        empty = np.zeros(0, np.int64)
        for f in scored.tolist():
            gidx = g_groups.get(f, empty)
            gidx = gidx[gt.targets[gidx]]
            pidx = p_groups.get(f, empty)
            pidx = pidx[~dropped[pidx]]
            oids, hids = gt.ids[gidx], pids[pidx]
            _check_unique(oids, "ground-truth", gt.source, f)
            _check_unique(hids, "prediction", preds.source, f)
            ious = box_iou(gt.boxes[gidx], preds.boxes[pidx])
            dist = np.where(ious >= iou, 1.0 - ious, np.nan)
            acc.update(oids.tolist(), hids.tolist(), dist, frameid=f)
            per_frame.append((oids, gt.boxes[gidx], hids, preds.boxes[pidx]))
        mh = mm.metrics.create()
        summary = mh.compute(acc, metrics=["mota", "motp", "idf1", "num_switches", "num_fragmentations",
                                           "num_objects"], name="all")
    h = hota(per_frame)
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
        "fragmentations": int(row["num_fragmentations"]),
        "hota": h.hota,
        "deta": h.deta,
        "assa": h.assa,
    }


# ---------------------------------------------------------------------------------------
# output

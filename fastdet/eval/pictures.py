"""Scores of a detector on labelled picture sets, one row per source: P / R / F1 / AP (IoU 0.5)
/ false alarms per picture / recall by box width.

Each picture (:class:`~fastdet.labels.AnnotatedPicture`) is matched on its own exactly as a
frame of a clip (:func:`~fastdet.eval.matching.match_frame`: greedy by score, each prediction
takes the free target of highest IoU at or above the threshold; an unmatched prediction whose
area lies at least half in one ignore region is *dropped*, neither hit nor false alarm).

Partial labels. On a picture with ``complete=False`` not every vehicle is labelled, so an
unmatched prediction there is not known to be wrong: its false alarms are **not counted**,
and a source with any such picture reports **recall only** (precision, F1, AP and false alarms
per picture are ``NaN``: ``n/a`` in the table, ``null`` in JSON).

Numbers: ``precision = TP / (TP + FP)``, ``recall = TP / targets``, ``F1 = 2 TP / (2 TP + FP +
FN)``, ``fa_per_picture = FP / pictures``; AP is VOC all-point AP of every non-dropped
prediction of the source ranked by score (ties: picture then prediction order).
Widths (recall by width) are in **reference pixels**: the picture scaled to 1280 columns (the
target rule is a fraction of the width; for a 16:9 picture the same as 720 rows), binned as
the clip report (:data:`fastdet.eval.sizes.REPORT_EDGES`).

Library::

    from fastdet.eval.pictures import score_pictures, score_source
    s = score_source("dawn_fog", pictures, [detect(p.load()) for p in pictures])
    s = score_pictures("dawn_fog", pictures, detect)        # loads and detects for you
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..detections import Detections
from ..labels import AnnotatedPicture
from .matching import average_precision, match_frame
from .sizes import REPORT_EDGES, WidthBin

#: width every picture is scaled to for the width bins (reference pixels)
REFERENCE_WIDTH = 1280


def _ratio(num: float, den: float) -> float:
    return float(num) / float(den) if den > 0 else math.nan


@dataclass(frozen=True, eq=False)
class SourceScore:
    """One source's scores (module docstring).

    pictures, targets: how many; complete: every picture's labels complete (else recall only);
    tp: targets found; fp: false alarms on complete pictures (0 when not ``complete``);
    dropped: predictions on ignore regions; seconds: time spent detecting (0 when not timed);
    widths: recall per width bin; ranked_tp: ``(K,) bool`` the non-dropped predictions of the
    complete pictures in AP order, True for a hit.
    """

    name: str
    pictures: int
    targets: int
    complete: bool
    tp: int
    fp: int
    dropped: int
    widths: tuple[WidthBin, ...]
    ranked_tp: np.ndarray
    iou: float = 0.5
    seconds: float = 0.0

    @property
    def recall(self) -> float:
        return _ratio(self.tp, self.targets)

    @property
    def precision(self) -> float:
        return _ratio(self.tp, self.tp + self.fp) if self.complete else math.nan

    @property
    def f1(self) -> float:
        return _ratio(2 * self.tp, 2 * self.tp + self.fp + self.targets - self.tp) if self.complete else math.nan

    @property
    def fa_per_picture(self) -> float:
        return _ratio(self.fp, self.pictures) if self.complete else math.nan

    @property
    def ap(self) -> float:
        if not self.complete:
            return math.nan
        return average_precision(self.ranked_tp, self.targets)[0]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (NaN as None)."""
        def num(v: float) -> float | None:
            return None if not math.isfinite(v) else v

        return {"pictures": self.pictures, "targets": self.targets, "complete": self.complete, "tp": self.tp,
                "fp": self.fp if self.complete else None, "dropped": self.dropped, "iou": self.iou,
                "precision": num(self.precision), "recall": num(self.recall), "f1": num(self.f1),
                "ap": num(self.ap), "fa_per_picture": num(self.fa_per_picture),
                "ms_per_picture": num(1e3 * self.seconds / self.pictures) if self.pictures and self.seconds else None,
                "recall_by_width": [{"bin": b.label, "lo": b.lo, "hi": None if math.isinf(b.hi) else b.hi,
                                     "found": b.found, "total": b.total,
                                     "recall": None if b.total == 0 else b.recall} for b in self.widths]}


def frames_ground_truth(pictures: Iterable[AnnotatedPicture], source: str = "labels") -> Detections:
    """Labelled frames of one video as a ground-truth table for :func:`fastdet.eval.evaluate`:
    each picture's targets (``consider`` True) and ignore regions (False) at its ``frame``."""
    boxes, frames, consider = [np.zeros((0, 4))], [np.zeros(0, np.int64)], [np.zeros(0, bool)]
    for p in pictures:
        boxes += [p.targets, p.ignores]
        frames.append(np.full(len(p.targets) + len(p.ignores), p.frame, np.int64))
        consider.append(np.r_[np.ones(len(p.targets), bool), np.zeros(len(p.ignores), bool)])
    return Detections(np.concatenate(boxes), frames=np.concatenate(frames), consider=np.concatenate(consider),
                      source=source)


def score_source(name: str, pictures: Sequence[AnnotatedPicture], predictions: Sequence[Detections],
                 iou: float = 0.5, edges: tuple[float, ...] = REPORT_EDGES, seconds: float = 0.0) -> SourceScore:
    """Score one source: ``predictions[i]`` are the boxes found in ``pictures[i]`` (module
    docstring); ``seconds``: the time the detection took, for the report."""
    if len(pictures) != len(predictions):
        raise ValueError(f"{len(pictures)} pictures but {len(predictions)} predictions")
    if not 0 < iou <= 1:
        raise ValueError(f"iou must be in (0, 1], got {iou!r}")
    complete = all(p.complete for p in pictures)
    tp = fp = dropped = targets = 0
    found = np.zeros(len(edges) - 1, np.int64)
    total = np.zeros(len(edges) - 1, np.int64)
    rank_scores: list[np.ndarray] = []
    rank_tp: list[np.ndarray] = []
    for pic, pred in zip(pictures, predictions):
        boxes = np.asarray(pred.boxes, np.float64).reshape(-1, 4)
        scores = np.asarray(pred.scores, np.float64).reshape(-1)
        hit, drop, gi = match_frame(boxes, scores, pic.targets, pic.ignores, iou)
        targets += len(pic.targets)
        tp += int(hit.sum())
        dropped += int(drop.sum())
        if pic.complete:
            fp += int((~hit & ~drop).sum())
            rank_scores.append(scores[~drop])
            rank_tp.append(hit[~drop])
        matched = np.zeros(len(pic.targets), bool)
        matched[gi[gi >= 0]] = True
        w = (pic.targets[:, 2] - pic.targets[:, 0]) * (REFERENCE_WIDTH / float(pic.width))
        b = np.searchsorted(edges, w, side="right") - 1
        ok = (b >= 0) & (b < len(edges) - 1)
        np.add.at(total, b[ok], 1)
        np.add.at(found, b[ok & matched], 1)
    s = np.concatenate(rank_scores) if rank_scores else np.zeros(0)
    t = np.concatenate(rank_tp) if rank_tp else np.zeros(0, bool)
    ranked = t[np.argsort(-s, kind="stable")]
    widths = tuple(WidthBin(edges[i], edges[i + 1], int(found[i]), int(total[i])) for i in range(len(edges) - 1))
    return SourceScore(name, len(pictures), targets, complete, tp, fp, dropped, widths, ranked, iou, seconds)


def score_pictures(name: str, pictures: Sequence[AnnotatedPicture], detect: Callable[[np.ndarray], Detections],
                   iou: float = 0.5, edges: tuple[float, ...] = REPORT_EDGES,
                   each: Callable[[AnnotatedPicture], None] | None = None) -> SourceScore:
    """:func:`score_source` of ``detect(pixels)`` on every picture (loaded one at a time:
    :meth:`AnnotatedPicture.load`, a :class:`~fastdet.errors.DataError` when one does not
    decode); ``each`` is called after each picture (a progress bar)."""
    import time

    preds = []
    spent = 0.0
    for pic in pictures:
        img = pic.load()
        t0 = time.perf_counter()
        preds.append(detect(img))
        spent += time.perf_counter() - t0
        if each is not None:
            each(pic)
    return score_source(name, pictures, preds, iou, edges, spent)


def _f(x: float, digits: int = 2) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.{digits}f}"


def markdown_rows(scores: Iterable[SourceScore]) -> list[str]:
    """Rows for the clip report's table (:func:`fastdet.eval.clips.markdown_table`): the same
    columns, ``N pic`` for the frames, false alarms per picture, ``n/a`` where a source is
    recall only."""
    lines = []
    for s in scores:
        row = [s.name + ("" if s.complete else " (recall only)"), f"{s.pictures} pic", str(s.targets),
               _f(s.precision), _f(s.recall), f"**{_f(s.f1)}**", _f(s.ap), _f(s.fa_per_picture), str(s.tp),
               str(s.fp) if s.complete else "n/a"]
        row += [f"{b.found}/{b.total}" if b.total else "-" for b in s.widths]
        lines.append("| " + " | ".join(row) + " |")
    return lines

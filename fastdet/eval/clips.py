"""One report over every annotated clip: per clip P / R / F1 / AP / false alarms per frame and
recall by box width, as a markdown table and as JSON.

The clips are the videos of a data folder that have ground truth
(``annotations/CLIP.gt.txt`` beside ``videos/CLIP.mp4``); a clip with a keyframe list
(``annotations/CLIP.frames``) is scored on its keyframes only (:mod:`fastdet.io.keyframes`).
Widths are in reference pixels (:mod:`.sizes`: the frame scaled to 720 rows, i.e. 1280-wide
pixels for 16:9), binned ``< 60``, ``60-120``, ``>= 120``.

Library::

    from fastdet.eval.clips import annotated_clips, score_clip, markdown_table, report_json
    scores = [score_clip(c.name, c.gt(), preds[c.name], frame_rows, c.keyframes()) for c in annotated_clips()]
    print(markdown_table(scores)); json.dumps(report_json(scores, settings={...}))

The command ``python -m fastdet eval --all`` runs the video pipeline over every clip and
prints this report.
"""
from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..data import data_dir
from ..detections import Detections
from ..io.keyframes import GT_SUFFIX, keyframes_for
from ..io.motfiles import read_gt
from .metrics import EvalResult, evaluate
from .pictures import SourceScore, markdown_rows
from .sizes import REPORT_EDGES, WidthBin, recall_by_width

#: version of the JSON report's layout (bumped when a field changes meaning)
REPORT_FORMAT = 1


@dataclass(frozen=True)
class AnnotatedClip:
    """A video with ground truth: ``name`` (``CLIP``), ``video`` (``videos/CLIP.mp4``),
    ``gt_path`` (``annotations/CLIP.gt.txt``)."""

    name: str
    video: Path
    gt_path: Path

    def gt(self) -> Detections:
        return read_gt(self.gt_path)

    def keyframes(self) -> np.ndarray | None:
        """The clip's keyframes, or None when every frame up to the last annotated one is."""
        return keyframes_for(self.gt_path)


def annotated_clips(data: str | os.PathLike[str] | None = None) -> list[AnnotatedClip]:
    """Every ``annotations/CLIP.gt.txt`` of the data folder (default :func:`fastdet.data.data_dir`)
    whose ``videos/CLIP.mp4`` exists, sorted by name."""
    root = Path(data) if data is not None else data_dir()
    out = []
    for gt in sorted((root / "annotations").glob("*" + GT_SUFFIX)):
        name = gt.name[: -len(GT_SUFFIX)]
        video = root / "videos" / f"{name}.mp4"
        if video.is_file():
            out.append(AnnotatedClip(name, video, gt))
    return out


@dataclass(frozen=True, eq=False)
class ClipScore:
    """One clip's scores: ``result`` (:func:`~fastdet.eval.evaluate`, keyframes only when the
    clip has them), ``widths`` (recall per width bin) and ``frame_rows`` (the clip's height)."""

    name: str
    result: EvalResult
    widths: tuple[WidthBin, ...]
    frame_rows: int

    def to_dict(self) -> dict[str, Any]:
        r = self.result.to_dict()
        r["frame_rows"] = self.frame_rows
        r["recall_by_width"] = [
            {"bin": b.label, "lo": b.lo, "hi": None if math.isinf(b.hi) else b.hi, "found": b.found,
             "total": b.total, "recall": None if b.total == 0 else b.recall} for b in self.widths]
        return r


def score_clip(name: str, gt: Detections, preds: Detections, frame_rows: int,
               keyframes: np.ndarray | None = None, iou: float = 0.5,
               edges: tuple[float, ...] = REPORT_EDGES) -> ClipScore:
    """Score one clip's predictions (module docstring); ``frame_rows``: the video's height in
    pixels (for the width bins)."""
    result = evaluate(gt, preds, iou=iou, keyframes=keyframes)
    widths = recall_by_width(gt, preds, frame_rows, iou=iou, edges=edges, keyframes=keyframes,
                             num_frames=None if keyframes is not None else result.frames)
    return ClipScore(name, result, tuple(widths), int(frame_rows))


def _f(x: float | None, digits: int = 2) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def markdown_table(scores: Sequence[ClipScore], pictures: Sequence[SourceScore] = ()) -> str:
    """The report as a markdown table, one row per clip, then one per picture set of
    ``pictures`` (:func:`fastdet.eval.pictures.markdown_rows`; no trailing newline)."""
    first = scores[0].widths if scores else pictures[0].widths if pictures else ()
    labels = [b.label for b in first]
    head = ["clip", "frames", "targets", "P", "R", "F1", "AP", "FA / frame", "TP", "FA"]
    head += [f"R w{lab}" for lab in labels]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for s in scores:
        r = s.result
        frames = f"{r.frames} kf" if r.keyframes else str(r.frames)
        row = [s.name, frames, str(r.num_gt), _f(r.precision), _f(r.recall), f"**{_f(r.f1)}**", _f(r.ap),
               _f(r.fp_per_frame), str(r.tp), str(r.fp)]
        row += [f"{b.found}/{b.total}" if b.total else "-" for b in s.widths]
        lines.append("| " + " | ".join(row) + " |")
    lines += markdown_rows(pictures)
    return "\n".join(lines)


def report_json(scores: Sequence[ClipScore], settings: dict[str, Any] | None = None,
                pictures: Sequence[SourceScore] = ()) -> dict[str, Any]:
    """The report as a JSON-ready dict: ``{"format", "iou", "settings", "clips": {name: ...}}``
    and, with ``pictures``, ``"pictures": {set name: ...}`` (NaN as null; keys in a stable
    order, so two reports diff line by line)."""
    iou = scores[0].result.iou_threshold if scores else pictures[0].iou if pictures else None
    out = {"format": REPORT_FORMAT, "iou": iou, "settings": dict(settings or {}),
           "clips": {s.name: s.to_dict() for s in scores}}
    if pictures:
        out["pictures"] = {s.name: s.to_dict() for s in pictures}
    return out

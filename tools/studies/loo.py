"""Pieces shared by the leave-one-clip-out studies (``model_loo``, ``options_table``): the folds
(which clips a held-out model may not see) and one clip's pipeline score.

A *fold* holds out one camera: every clip of it is scored only by a model trained on the clips
of the other cameras. Clips of one camera (``same_camera``: the two Udacity clips, cut from one
drive) form one fold, so neither is scored by a model that saw the other.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from fastdet.boxes import intersection, iou
from fastdet.config import PipelineConfig
from fastdet.detections import Detections
from fastdet.eval.clips import AnnotatedClip, ClipScore, score_clip
from fastdet.video.run import iter_video_detections

#: clips cut from one camera's footage (one drive): held out together
SAME_CAMERA: tuple[tuple[str, ...], ...] = (("test_small1", "test_video"),)


@dataclass(frozen=True)
class Fold:
    """``held_out``: the clips scored; ``train``: the clips a model for them may learn from."""

    held_out: tuple[str, ...]
    train: tuple[str, ...]

    @property
    def name(self) -> str:
        return "+".join(self.held_out)


def folds(names: Sequence[str], same_camera: Sequence[Sequence[str]] = SAME_CAMERA) -> list[Fold]:
    """One fold per camera among ``names`` (clips of a ``same_camera`` group together, every
    other clip alone), in the order of each fold's first clip in ``names``."""
    group_of = {n: tuple(c for c in g if c in names) for g in same_camera for n in g if n in names}
    out: list[Fold] = []
    seen: set[str] = set()
    for n in names:
        if n in seen:
            continue
        held = group_of.get(n, (n,))
        seen.update(held)
        out.append(Fold(held, tuple(c for c in names if c not in held)))
    return out


def frame_rows(clip: AnnotatedClip) -> int:
    """The clip's frame height in pixels."""
    cap = cv2.VideoCapture(str(clip.video))
    try:
        return int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    finally:
        cap.release()


def run_clip(clip: AnnotatedClip, config: PipelineConfig, keep: list[Detections] | None = None) -> ClipScore:
    """The video pipeline with ``config`` over ``clip``, scored as ``fastdet eval --all`` scores
    it (keyframes only on a keyframe clip, IoU 0.5); ``keep``: a list the boxes are appended to."""
    preds = Detections.from_frames(iter_video_detections(clip.video, config, progress=False), source=str(clip.video))
    if keep is not None:
        keep.append(preds)
    return score_clip(clip.name, clip.gt(), preds, frame_rows(clip), clip.keyframes())


def misplaced(clip: AnnotatedClip, preds: Detections, iou_min: float = 0.5) -> tuple[int, int]:
    """``(near, clear)``: of the boxes ``preds`` has on the clip's scored frames (its keyframes,
    or every frame) that reach IoU ``iou_min`` with no target and touch no ignore region, those
    touching a target (too big, over two vehicles, beside one) and those touching no annotated box."""
    gt = clip.gt()
    by_frame = dict(gt.by_frame())
    keyframes = clip.keyframes()
    scored = None if keyframes is None else set(int(k) for k in keyframes)
    near = clear = 0
    for frame, d in preds.by_frame():
        if scored is not None and frame not in scored:
            continue
        g = by_frame.get(frame)
        boxes = d.boxes.astype(float)
        targets = g.boxes[g.targets].astype(float) if g is not None else np.zeros((0, 4))
        ignores = g.boxes[~g.targets].astype(float) if g is not None else np.zeros((0, 4))
        hit = (iou(boxes, targets) >= iou_min).any(1) if len(targets) else np.zeros(len(boxes), bool)
        ign = (intersection(boxes, ignores) > 0).any(1) if len(ignores) else np.zeros(len(boxes), bool)
        touch = (intersection(boxes, targets) > 0).any(1) if len(targets) else np.zeros(len(boxes), bool)
        near += int((~hit & ~ign & touch).sum())
        clear += int((~hit & ~ign & ~touch).sum())
    return near, clear

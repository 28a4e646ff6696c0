"""A model judged on every window of annotated frames, wherever the search would put its bands:
the *placement-free* window score, and the false windows a model fires on there (hard negatives).

The pipeline's score of a model on a camera mixes two things: how well the model tells vehicles
from background, and whether the search bands put windows of the right size where that
camera's vehicles are. :func:`dense_search` takes the second out: bands over the whole frame
height at every window size from ``min_width`` of the frame width to the frame height, ``steps``
sizes per octave, windows ``cells_per_step`` HOG cells apart. On every annotated frame
(:class:`~fastdet.train.keyframes.AnnotatedFrame`) :func:`frame_windows` then gives

- per target, the best score of a window whose IoU with it is at least ``iou`` (``-inf``
  when none is: a square window cannot reach IoU 0.5 with a box more than twice as wide as
  tall);
- the scores of the *false* windows: those touching no annotated box, target or ignore
  region alike (a far-away or half-hidden vehicle is neither);
- the scores of the *near* windows: those that touch a target but overlap every target at
  IoU below ``near_iou`` (0.3) and touch no ignore region: a window on part of a vehicle, or
  one much bigger than it (hard negatives that teach where a vehicle's box is).

:func:`window_score` sums those up over frames: recall (the fraction of targets whose best
window beats a threshold) at the thresholds that let 0.1, 1 and 10 false windows per frame
through, and at probability 0.5 (the search's threshold) with the false windows per frame
there.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..boxes import intersection, iou
from ..config import SearchBand, SearchConfig
from ..detections import FIRST_COMPONENT_PART, MAIN_PART, ONCOMING_PART
from ..model import Model
from .keyframes import AnnotatedFrame

#: false windows per frame at which :class:`WindowScore` reports recall
FALSE_RATES = (0.1, 1.0, 10.0)


def dense_search(frame_shape: tuple[int, int], window: int = 64, min_width: float = 1 / 32,
                 steps: int = 4, cells_per_step: int = 1, threshold: float = -math.inf,
                 cell: int = 8) -> SearchConfig:
    """A search over every row of a ``frame_shape = (H, W)`` frame at every window size from
    ``min_width x W`` up to ``H`` pixels, ``steps`` sizes per octave (``window``: the model's
    window width at scale 1, ``cell``: its HOG cell). Bands in the frame's own pixels
    (``reference_shape`` None), no window over the frame edge (``border`` 0). ``threshold``
    -inf: every window is returned."""
    h, w = (int(v) for v in frame_shape[:2])
    if min(h, w) < window or not 0 < min_width <= 1 or steps < 1:
        raise ValueError(f"dense_search: frame {w}x{h}, min_width {min_width}, steps {steps}")
    lo = max(min_width * w, 2 * cell) / window
    n = int(math.floor(steps * math.log2(h / window / lo))) + 1
    bands = []
    for k in range(max(n, 1)):
        s = lo * 2 ** (k / steps)
        if window * s <= h:
            bands.append(SearchBand(s, 0, h, 0, int(w // (cell * s) * cell * s) or w))
    return SearchConfig(bands=tuple(bands), cells_per_step=cells_per_step, threshold=threshold,
                        reference_shape=None, border=0.0)


@dataclass(frozen=True)
class FrameWindows:
    """One annotated frame's windows: ``best (N,)`` the best score of a window at IoU >=
    ``iou`` with each target (``-inf``: none), ``false (K,)`` the scores of the windows that
    touch no annotated box, ``false_boxes (K, 4)`` those windows; ``near (J,)`` and
    ``near_boxes (J, 4)`` the near windows (module docstring; empty when not asked for)."""

    best: np.ndarray
    false: np.ndarray
    false_boxes: np.ndarray
    near: np.ndarray = field(default_factory=lambda: np.zeros(0))
    near_boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))


def frame_windows(detector: Any, frame: AnnotatedFrame, iou_min: float = 0.5,
                  parts: Sequence[int] | None = (MAIN_PART,), min_false: float = -math.inf,
                  near_iou: float | None = None) -> FrameWindows:
    """Score every window ``detector`` (a :class:`fastdet.Detector`) searches in ``frame`` with
    its models ``parts`` (``None``: all but the oncoming model; module docstring); false windows
    (and near windows) are kept only above ``min_false``; near windows only with ``near_iou``
    (the IoU every target must stay below, in (0, ``iou_min``])."""
    if near_iou is not None and not 0 < near_iou <= iou_min:
        raise ValueError(f"frame_windows: near_iou must be in (0, {iou_min}], got {near_iou!r}")
    d = detector.detect(frame.image)
    d = d[d.part != ONCOMING_PART] if parts is None else d[np.isin(d.part, list(parts))]
    boxes = d.boxes.astype(np.float64)
    scores = d.scores.astype(np.float64)
    best = np.full(len(frame.targets), -np.inf)
    near = np.zeros(len(boxes), bool)
    if len(frame.targets) and len(boxes):
        ious = iou(boxes, frame.targets)
        ov = ious >= iou_min
        for j in range(len(frame.targets)):
            if ov[:, j].any():
                best[j] = scores[ov[:, j]].max()
        if near_iou is not None:
            near = (ious.max(axis=1) < near_iou) & np.any(intersection(boxes, frame.targets) > 0, axis=1)
            if len(frame.ignores):
                near &= ~np.any(intersection(boxes, frame.ignores) > 0, axis=1)
            near &= scores > min_false
    keep = scores > min_false
    annotated = frame.boxes
    if len(annotated):
        keep &= ~np.any(intersection(boxes, annotated) > 0, axis=1)
    return FrameWindows(best, scores[keep], boxes[keep], scores[near], boxes[near])


@dataclass(frozen=True)
class WindowScore:
    """Placement-free score of a model over annotated frames (:func:`window_score`).

    targets: how many; reachable: how many have a window at IoU >= 0.5 at all;
    recall_at: ``{false windows per frame: recall}`` (:data:`FALSE_RATES`);
    recall_half / false_half: recall and false windows per frame at probability 0.5.
    """

    frames: int
    targets: int
    reachable: int
    recall_at: dict[float, float]
    recall_half: float
    false_half: float

    def to_dict(self) -> dict[str, Any]:
        return {"frames": self.frames, "targets": self.targets, "reachable": self.reachable,
                "recall_at": {str(k): v for k, v in self.recall_at.items()}, "recall_half": self.recall_half,
                "false_half": self.false_half}


def window_score(windows: Sequence[FrameWindows], half: float = 0.5,
                 rates: Iterable[float] = FALSE_RATES) -> WindowScore:
    """Sum up :func:`frame_windows` of several frames (module docstring). Probabilities are
    compared with ``half``; the thresholds for ``rates`` false windows per frame are the
    scores of the ``rate x frames``-th best false window."""
    n = len(windows)
    best = np.concatenate([w.best for w in windows]) if n else np.zeros(0)
    false = np.sort(np.concatenate([w.false for w in windows]))[::-1] if n else np.zeros(0)
    recall_at = {}
    for r in rates:
        k = int(round(r * n))
        t = false[k - 1] if 0 < k <= len(false) else (-np.inf if k > len(false) else np.inf)
        recall_at[float(r)] = float((best > t).mean()) if len(best) else math.nan
    return WindowScore(n, len(best), int(np.isfinite(best).sum()), recall_at,
                       float((best > half).mean()) if len(best) else math.nan,
                       float((false > half).sum() / max(n, 1)))


def dense_detector(model: Model, frame_shape: tuple[int, int], components: Sequence[Model] = (),
                   **search: Any) -> Any:
    """A :class:`fastdet.Detector` of ``model`` (and ``components``: more models scored on the
    same windows, :func:`false_window_scores`) with :func:`dense_search` for frames of
    ``frame_shape``, each model's for its own window (``search``: its keyword arguments). The
    models' own windows only: a side-view component a model carries (:attr:`Model.side
    <fastdet.model.Model.side>`) is not searched."""
    from ..detect import Detector

    def dense(m: Model) -> SearchConfig:
        return dense_search(frame_shape, m.config.win_w, cell=m.config.pixels_per_cell, **search)

    return Detector(model, dense(model), components=[(c, dense(c)) for c in components], side=False)


def score_frames(model: Model, frames: Sequence[AnnotatedFrame], iou_min: float = 0.5,
                 on_frame: Callable[[AnnotatedFrame, FrameWindows], None] | None = None,
                 near_iou: float | None = None, **search: Any) -> WindowScore:
    """:func:`window_score` of ``model`` over ``frames``, every window of :func:`dense_search`
    (``search``: its keyword arguments) searched. ``on_frame`` sees each frame's
    :class:`FrameWindows` (e.g. to keep its false windows as hard negatives; its near windows
    with ``near_iou``, :func:`frame_windows`)."""
    detectors: dict[tuple[int, int], Any] = {}
    out = []
    for f in frames:
        shape = f.image.shape[:2]
        if shape not in detectors:
            detectors[shape] = dense_detector(model, shape, **search)
        fw = frame_windows(detectors[shape], f, iou_min, parts=None, near_iou=near_iou)
        if on_frame is not None:
            on_frame(f, fw)
        out.append(fw)
    return window_score(out)


def false_window_scores(models: Sequence[Model], frames: Sequence[AnnotatedFrame], **search: Any) -> np.ndarray:
    """``(len(models), K) float64``: each model's decision values on the same ``K`` false windows
    (touching no annotated box) of ``frames``, every window of :func:`dense_search` (``search``:
    its keyword arguments, e.g. ``cells_per_step=2``) scored in one search (the models must share
    one window size and HOG cell), e.g. to compare how many background windows each lets through
    (:func:`fastdet.train.blend.rate_offset`)."""
    def clear(boxes: np.ndarray, f: AnnotatedFrame) -> np.ndarray:
        return ~np.any(intersection(boxes, f.boxes) > 0, axis=1) if len(f.boxes) else np.ones(len(boxes), bool)

    return _shared_window_scores(models, frames, clear, "false_window_scores", search)


def near_window_scores(models: Sequence[Model], frames: Sequence[AnnotatedFrame], near_iou: float = 0.3,
                       **search: Any) -> np.ndarray:
    """As :func:`false_window_scores` for the near windows of ``frames`` (touching a target, IoU
    below ``near_iou`` with every target, touching no ignore region; :func:`frame_windows`): the
    windows partly on a vehicle that the heat map grows into misplaced boxes."""
    if not 0 < near_iou <= 0.5:
        raise ValueError(f"near_window_scores: near_iou must be in (0, 0.5], got {near_iou!r}")

    def near(boxes: np.ndarray, f: AnnotatedFrame) -> np.ndarray:
        if not len(f.targets) or not len(boxes):
            return np.zeros(len(boxes), bool)
        keep = (iou(boxes, f.targets).max(axis=1) < near_iou) & np.any(intersection(boxes, f.targets) > 0, axis=1)
        if len(f.ignores):
            keep &= ~np.any(intersection(boxes, f.ignores) > 0, axis=1)
        return keep

    return _shared_window_scores(models, frames, near, "near_window_scores", search)


def _shared_window_scores(models: Sequence[Model], frames: Sequence[AnnotatedFrame],
                          select: Callable[[np.ndarray, AnnotatedFrame], np.ndarray], name: str,
                          search: dict[str, Any]) -> np.ndarray:
    """Every model's decision values on the dense windows of ``frames`` that ``select(boxes,
    frame)`` keeps (a boolean mask), ``(len(models), K)``."""
    from ..detect.bands import window_boxes
    from ..detect.detector import DetectStats

    if not models:
        raise ValueError(f"{name}: no model")
    first = models[0].config
    for m in models[1:]:
        if (m.config.win_w, m.config.win_h, m.config.pixels_per_cell) != (first.win_w, first.win_h,
                                                                            first.pixels_per_cell):
            raise ValueError(f"{name}: the models' windows or HOG cells differ")
    parts = [MAIN_PART] + [FIRST_COMPONENT_PART + i for i in range(len(models) - 1)]
    detectors: dict[tuple[int, int], Any] = {}
    out: list[np.ndarray] = []
    for f in frames:
        shape = f.image.shape[:2]
        if shape not in detectors:
            detectors[shape] = dense_detector(models[0], shape, models[1:], **search)
        st = DetectStats()
        detectors[shape].detect(f.image, stats=st)
        boxes: dict[int, list[np.ndarray]] = {p: [] for p in parts}
        decs: dict[int, list[np.ndarray]] = {p: [] for p in parts}
        for part, geo, dec in st.bands:
            r, c = np.nonzero(np.isfinite(dec))
            boxes[part].append(window_boxes(geo, r, c, first).astype(np.float64))
            decs[part].append(dec[r, c].astype(np.float64))
        b0 = np.concatenate(boxes[MAIN_PART]) if boxes[MAIN_PART] else np.zeros((0, 4))
        for p in parts[1:]:
            bp = np.concatenate(boxes[p]) if boxes[p] else np.zeros((0, 4))
            if not np.array_equal(bp, b0):
                raise AssertionError(f"{name}: the models' searches gave other windows")
        keep = select(b0, f)
        out.append(np.stack([np.concatenate(decs[p])[keep] if decs[p] else np.zeros(0) for p in parts]))
    return np.concatenate(out, axis=1) if out else np.zeros((len(models), 0))

"""The operating point of a camera's model (``python -m fastdet adapt``): the box formation and
decision offset under which the ``video`` pipeline agrees best with the labels of the frames kept
aside, chosen over one replay of every lane (:func:`choose_operating_point`), the offset by the
one-standard-error rule (:func:`strictest_within_one_se`). The runs themselves (the pipeline and
the scoring) are given by the caller, :mod:`fastdet.cli.adapt`; the model's training is
:mod:`fastdet.train.adapt`'s."""
from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from tqdm import tqdm

from ..config import BOXES, Boxes
from ..model import Model
from .adapt import Clip, Footage
from .blend import offset


@dataclass(frozen=True)
class Agreement:
    """Boxes against the labels of the kept-aside frames (IoU 0.5): hits, false alarms, misses."""

    tp: int
    fp: int
    fn: int
    seconds: float
    frames: int

    @property
    def precision(self) -> float:
        return self.tp / (self.tp + self.fp) if self.tp + self.fp else math.nan

    @property
    def recall(self) -> float:
        return self.tp / (self.tp + self.fn) if self.tp + self.fn else math.nan

    @property
    def f1(self) -> float:
        d = 2 * self.tp + self.fp + self.fn
        return 2 * self.tp / d if d else math.nan

    @property
    def ms_per_frame(self) -> float:
        """The pipeline's wall time per frame (ms) after each stretch's first frame: the steady
        frame loop, without the start-up (reaching the stretch, the horizon from its first frames);
        ``adapt`` feeds it the stretch's frames decoded once and held
        (:func:`fastdet.cli.kept_aside.held_stretches`), so it holds no decoding either."""
        return 1000.0 * self.seconds / self.frames if self.frames else math.nan

    def to_dict(self) -> dict[str, Any]:
        def num(v: float) -> float | None:
            return None if math.isnan(v) else round(v, 4)

        return {"f1": num(self.f1), "precision": num(self.precision), "recall": num(self.recall),
                "tp": self.tp, "fp": self.fp, "fn": self.fn, "ms_per_frame": num(self.ms_per_frame)}


#: ``run(clip, model file or None for the bundled one) -> (tp, fp, fn, seconds, frames)``:
#: the video pipeline over the clip's kept-aside stretch, scored against its kept-aside labels
#: (``seconds`` and ``frames`` from the stretch's first frame out: :attr:`Agreement.ms_per_frame`)
HoldoutRun = Callable[[Clip, "str | None"], tuple[int, int, int, float, int]]

#: one lane of a :data:`LanesRun`: ``(boxes, offset)``, or ``(boxes, offset, side offset)`` for a
#: model carrying a side-view component (+inf: without it; :func:`~fastdet.train.blend.side_offset`)
Lane = tuple[Boxes, float] | tuple[Boxes, float, float]

#: ``run(clip, model file, lanes) -> ({lane: counts (K, 3) int64}, seconds, frames read)``:
#: the video pipeline over the clip's kept-aside stretch for each lane -- a box formation
#: (:attr:`PipelineConfig.boxes <fastdet.config.PipelineConfig>`) and the model moved by an offset
#: (:func:`~fastdet.train.blend.offset`); the frames read and scored once for all of them:
#: :func:`fastdet.video.replay.iter_lane_detections` --, each lane's boxes scored against the
#: kept-aside labels: ``(tp, fp, fn)`` of each of the clip's K kept-aside labelled frames, in one
#: frame order for every lane
LanesRun = Callable[[Clip, str, Sequence[Lane]], tuple[dict[Lane, np.ndarray], float, int]]

#: bootstrap draws of the kept-aside frames for the standard error of the best offset's F1
#: (:func:`strictest_within_one_se`)
BOOTSTRAP_DRAWS = 200


def agreement(footage: Footage, run: HoldoutRun, model_path: str | None) -> Agreement:
    """``run`` over every clip with kept-aside labels, summed."""
    tp = fp = fn = frames = 0
    secs = 0.0
    for clip in footage.clips:
        if not clip.holdout_frames(footage.holdout_every):
            continue
        a, b, c, s, n = run(clip, model_path)
        tp, fp, fn, secs, frames = tp + a, fp + b, fn + c, secs + s, frames + n
    return Agreement(tp, fp, fn, secs, frames)


class FormationChoice(NamedTuple):
    """One box formation's operating point (:func:`choose_operating_point`): ``offset`` chosen
    (:func:`strictest_within_one_se`), ``results`` (every offset's :class:`Agreement`), ``best``
    (the offset of best F1) and ``se`` (the bootstrap standard error of that F1)."""

    offset: float
    results: dict[float, Agreement]
    best: float
    se: float


def _f1(counts: np.ndarray) -> np.ndarray:
    """F1 of ``(..., K, 3)`` per-frame (tp, fp, fn) summed over the frames (0 where undefined)."""
    tp, fp, fn = np.moveaxis(counts.sum(axis=-2), -1, 0)
    d = 2 * tp + fp + fn
    return np.where(d > 0, 2 * tp / np.maximum(d, 1), 0.0)


def strictest_within_one_se(per_frame: Mapping[float, np.ndarray], seed: int = 0,
                            draws: int = BOOTSTRAP_DRAWS) -> tuple[float, float, float]:
    """``(chosen, best, se)`` of one formation's offsets by the one-standard-error rule (Breiman
    et al., *Classification and Regression Trees*, 1984; Hastie, Tibshirani and Friedman, *The
    Elements of Statistical Learning*, 7.10): ``best`` is the offset of best F1 against the
    kept-aside labels (ties: the one nearest 0), ``se`` the standard error of its F1 over the
    kept-aside frames (``draws`` bootstrap resamples of the frames, seeded by ``seed``), and
    ``chosen`` the strictest offset (the largest: the fewest boxes) whose F1 is within ``se`` of
    the best. On a handful of kept-aside frames the F1s of neighbouring offsets differ by less
    than their noise; the teacher also boxes far-away traffic that human labels leave out, so
    the best F1 against it leans to loose offsets (docs/training.md, "The operating point within
    one standard error"). Where the offsets next to the strictest one give the very same counts
    on every frame, the frames cannot tell them apart, and the one of them nearest 0 is chosen
    (a flat run over 3 frames otherwise sends the choice to its strict end for no evidence).
    ``per_frame``: each offset's ``(K, 3)`` per-frame (tp, fp, fn), one frame order."""
    offsets = sorted(per_frame)
    if not offsets:
        raise ValueError("no offsets to choose from")
    counts = np.stack([np.asarray(per_frame[o], np.int64).reshape(-1, 3) for o in offsets])
    f1 = _f1(counts)
    # rank by F1 (an undefined one, no boxes and no targets, lowest), ties nearest 0
    defined = counts.sum(axis=(1, 2)) > 0
    rank = [(f1[i] if defined[i] else -1.0, -abs(o)) for i, o in enumerate(offsets)]
    ib = max(range(len(offsets)), key=lambda i: rank[i])
    k = counts.shape[1]
    if not defined[ib] or k < 2:
        return offsets[ib], offsets[ib], 0.0
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, k, (draws, k))
    se = float(np.std(_f1(counts[ib][idx])))
    within = [i for i in range(len(offsets)) if defined[i] and f1[i] >= f1[ib] - se]
    return offsets[_nearest_zero_alike(counts, offsets, max(within))], offsets[ib], se


def _nearest_zero_alike(counts: np.ndarray, offsets: Sequence[float], i: int) -> int:
    """Of the run of neighbouring offsets around ``offsets[i]`` whose boxes agree with the labels
    exactly as its do (the same counts on every frame), the one nearest 0: across that run the
    kept-aside frames tell nothing apart, and the model's own calibration stands."""
    lo = hi = i
    while lo > 0 and np.array_equal(counts[lo - 1], counts[i]):
        lo -= 1
    while hi < len(offsets) - 1 and np.array_equal(counts[hi + 1], counts[i]):
        hi += 1
    return min(range(lo, hi + 1), key=lambda j: (abs(offsets[j]), -offsets[j]))


def choose_boxes(by_boxes: Mapping[str, FormationChoice]) -> Boxes:
    """The box formation (:data:`fastdet.config.BOXES`) that agrees best with the labels kept
    aside, by the F1 at its best offset: ``by_boxes`` maps each formation to its
    :class:`FormationChoice`. Ties, or no F1 at all, keep ``'heat'`` (the pipeline's own)."""
    def rank(b: str) -> tuple[float, bool]:
        choice = by_boxes[b]
        f1 = choice.results[choice.best].f1
        return (-1.0 if math.isnan(f1) else f1, b == "heat")

    best = max(by_boxes, key=rank)
    if best not in BOXES:
        raise ValueError(f"unknown box formation {best!r}")
    return best  # type: ignore[return-value]


def lane_counts(model: Model, footage: Footage, run: LanesRun, folder: Path, lanes: Sequence[Lane], desc: str,
                progress: bool = True) -> tuple[dict[Lane, np.ndarray], float, int]:
    """``run`` over every clip with kept-aside labels for every lane at once: ``({lane: per-frame
    (tp, fp, fn) (K, 3) over all the clips}, seconds, frames read)``; ``model`` is written to
    ``folder`` for it to load (and removed after)."""
    folder.mkdir(parents=True, exist_ok=True)
    parts: dict[Lane, list[np.ndarray]] = {k: [] for k in lanes}
    secs, frames = 0.0, 0
    path = folder / "model.npz"
    offset(model, 0.0).save(path)
    try:
        for clip in tqdm([c for c in footage.clips if c.holdout_frames(footage.holdout_every)], desc=desc,
                         unit="video", file=sys.stderr, dynamic_ncols=True, disable=not progress):
            per_lane, s, n = run(clip, str(path), lanes)
            secs, frames = secs + s, frames + n
            for k in lanes:
                parts[k].append(np.asarray(per_lane[k], np.int64).reshape(-1, 3))
    finally:
        path.unlink(missing_ok=True)
    return {k: np.concatenate(v) if v else np.zeros((0, 3), np.int64) for k, v in parts.items()}, secs, frames


def choose_operating_point(model: Model, footage: Footage, run: LanesRun, folder: Path, offsets: Sequence[float],
                           formations: Sequence[Boxes] = BOXES, progress: bool = True, seed: int = 0
                           ) -> tuple[Boxes, float, dict[str, FormationChoice]]:
    """The box formation and decision offset for the model: for each of ``formations``, the
    offset :func:`strictest_within_one_se` picks from the per-frame agreement with the kept-aside
    labels (``seed``: its bootstrap's); of those, the formation :func:`choose_boxes` picks.
    Returns ``(formation, offset, {formation: FormationChoice})`` (each Agreement's ``seconds``:
    the whole run's over every clip, every lane at once). ``run`` gets every (formation, offset)
    lane at once; ``model`` is written to ``folder`` for it to load (and removed after)."""
    lanes: list[Lane] = [(b, float(o)) for b in formations for o in offsets]
    counts, secs, frames = lane_counts(model, footage, run, folder, lanes, "operating point", progress)
    by_boxes: dict[str, FormationChoice] = {}
    for b in formations:
        per_frame = {lane[1]: counts[lane] for lane in lanes if lane[0] == b}
        results = {o: Agreement(*(int(v) for v in c.sum(axis=0)), seconds=secs, frames=frames)
                   for o, c in per_frame.items()}
        chosen, best, se = strictest_within_one_se(per_frame, seed)
        by_boxes[b] = FormationChoice(chosen, results, best, se)
    boxes = choose_boxes(by_boxes)
    return boxes, by_boxes[boxes].offset, by_boxes


def choose_side_offset(model: Model, footage: Footage, run: LanesRun, folder: Path, boxes: Boxes, main_offset: float,
                       side_offsets: Sequence[float], progress: bool = True, seed: int = 0) -> FormationChoice:
    """The decision offset of ``model``'s side-view component (:attr:`Model.side`), or none
    (``math.inf``: the component left out), with the box formation ``boxes`` and the main model
    moved by ``main_offset`` (both chosen before, :func:`choose_operating_point`): of
    ``side_offsets`` and leaving it out, the strictest whose F1 against the kept-aside labels is
    within one standard error of the best (:func:`strictest_within_one_se`; leaving it out is the
    strictest of all), and leaving it out wherever an offset's boxes agree with the labels
    exactly as those without it do (the component would cost time for nothing). Returns the
    choice as a :class:`FormationChoice` over those offsets."""
    if model.side is None:
        raise ValueError("choose_side_offset: the model carries no side-view component")
    keys = [*sorted({float(o) for o in side_offsets}), math.inf]
    lanes: list[Lane] = [(boxes, float(main_offset), k) for k in keys]
    counts, secs, frames = lane_counts(model, footage, run, folder, lanes, "side-view offset", progress)
    per_frame = {lane[2]: counts[lane] for lane in lanes}  # type: ignore[misc]
    results = {k: Agreement(*(int(v) for v in c.sum(axis=0)), seconds=secs, frames=frames)
               for k, c in per_frame.items()}
    chosen, best, se = strictest_within_one_se(per_frame, seed)
    if np.array_equal(per_frame[chosen], per_frame[math.inf]):
        chosen = math.inf
    return FormationChoice(chosen, results, best, se)


def use_side(boxes: Boxes, by_boxes: Mapping[str, FormationChoice], side: FormationChoice) -> bool:
    """Whether the model keeps its side-view component: the offset :func:`choose_side_offset` chose
    (``side``) is not "left out" (+inf), and either the formation chosen without it (``boxes``) is
    the window boxes, or the window boxes with it agree with the kept-aside labels better (a
    higher F1, at the component's chosen offset) than that formation at its best offset: the
    component's windows go to the window boxes only, so a heat-map camera switches for a gain."""
    if side.offset == math.inf:
        return False
    if boxes == "nms":
        return True
    mine = side.results[side.offset].f1
    theirs = by_boxes[boxes].results[by_boxes[boxes].best].f1
    return not math.isnan(mine) and (math.isnan(theirs) or mine > theirs)

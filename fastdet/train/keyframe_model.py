"""The main (64x64, rear-view) model trained on the data set's crops **plus** crops cut from the
annotated frames of video clips: vehicles of other kinds and views (vans, trucks, SUVs, side
and angled views) and the backgrounds of other cameras (dashboards, hoods, city streets).

From the annotated frames (:mod:`fastdet.train.keyframes`; only annotated frames, a keyframe
clip's other frames have no labels) :func:`keyframe_crops` cuts

- positives: every annotated target grown to a square window
  (:func:`~fastdet.train.keyframes.window_around`, ``margin`` of context) plus ``jitter``
  moved and rescaled copies; :func:`fastdet.train.fit.train` mirrors them as the data set's
  vehicles;
- background: ``background`` random windows per frame touching no annotated box;
- hard negatives: the windows a model (default the bundled one) gives a probability above
  ``hard_threshold`` in a search of every row and size of the frame
  (:func:`fastdet.train.windows.dense_search`, so the negatives do not depend on where
  today's search bands are) that touch no annotated box, target or ignore region alike; at
  most ``hard_per_frame`` per frame (a seeded random choice);
- near misses (``near_per_frame`` > 0): the windows that model gives a probability above
  ``hard_threshold`` that touch a target yet overlap every target at IoU below ``near_iou``
  and touch no ignore region (on part of a vehicle, or far bigger than it: the windows the
  heat map grows into misplaced boxes), at most ``near_per_frame`` per frame.

:func:`train_keyframe_model` adds them to :func:`fastdet.train.fit.train`'s training set. Which
clips a model learns from is the caller's choice: a clip it saw must not score it (leave one
clip out: ``tools/studies/model_loo.py``).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..config import FeatureConfig
from ..model import Model, load_model
from .dataset import CropSet
from .fit import train
from .keyframes import AnnotatedFrame, background_crops, false_window_crops, positive_crops, window_crops
from .windows import FrameWindows, score_frames


@dataclass(frozen=True)
class KeyframeRecipe:
    """What :func:`keyframe_crops` cuts from the annotated frames (module docstring).

    margin: context around a positive, a fraction of its window on each side.
    jitter: moved (up to 5% of the window) and rescaled (0.9-1.1x) copies per positive.
    max_aspect: only targets narrower than this (width / height) are positives (the wider ones
        are left out); ``inf``: all.
    background: random windows per frame touching no annotated box.
    hard_per_frame: at most this many hard negatives per frame and round; hard_threshold: the
        probability above which a window is one (the search's 0.5).
    hard_rounds: rounds of mining (:func:`train_keyframe_model`): the first mines the given
        model's false windows, each later one those of the model the round before trained.
    near_per_frame: at most this many near misses per frame and round (0: none); near_iou: the
        IoU with every target they stay below.
    seed: every random choice.
    """

    margin: float = 0.0625
    jitter: int = 8
    max_aspect: float = float("inf")
    background: int = 20
    hard_per_frame: int = 40
    hard_threshold: float = 0.5
    hard_rounds: int = 1
    near_per_frame: int = 0
    near_iou: float = 0.3
    seed: int = 0

    def __post_init__(self) -> None:
        if min(self.jitter, self.background, self.hard_per_frame, self.near_per_frame) < 0 or self.margin < 0:
            raise ValueError("margin, jitter, background, hard_per_frame and near_per_frame must be >= 0")
        if not 0 < self.near_iou <= 0.5:
            raise ValueError(f"near_iou must be in (0, 0.5], got {self.near_iou!r}")
        if not self.max_aspect > 0:
            raise ValueError(f"max_aspect must be > 0, got {self.max_aspect!r}")
        if self.hard_rounds < 1:
            raise ValueError(f"hard_rounds must be >= 1, got {self.hard_rounds!r}")
        if not 0 < self.hard_threshold < 1:
            raise ValueError(f"hard_threshold must be a probability in (0, 1), got {self.hard_threshold!r}")

    def to_dict(self) -> dict[str, Any]:
        """The fields, JSON-ready (``max_aspect`` inf as ``None``)."""
        d = asdict(self)
        d["max_aspect"] = None if np.isinf(self.max_aspect) else float(self.max_aspect)
        return d


def _labelled(images: np.ndarray, label: int, group: str | list[str]) -> CropSet:
    groups = np.array([group] * len(images) if isinstance(group, str) else group, dtype=object).astype(str)
    return CropSet(images, np.full(len(images), label, np.int64), groups.reshape(-1), np.arange(len(images)))


def mine_hard(frames: Sequence[AnnotatedFrame], model: Model, recipe: KeyframeRecipe, win: int,
              seed: int) -> tuple[np.ndarray, int]:
    """``(crops (N, win, win, 3) uint8, fired)``: the false windows ``model`` gives a probability
    above ``recipe.hard_threshold`` in a dense search of ``frames`` (every second HOG cell), at
    most ``recipe.hard_per_frame`` per frame (seeded), then its near misses there (at most
    ``recipe.near_per_frame`` per frame; module docstring), cut to ``win x win``; ``fired``: how
    many false windows there were before the limit."""
    fired: list[np.ndarray] = []
    near: list[np.ndarray] = []

    def keep(_f: AnnotatedFrame, fw: FrameWindows) -> None:
        fired.append(fw.false_boxes[fw.false > recipe.hard_threshold])
        near.append(fw.near_boxes[fw.near > recipe.hard_threshold])

    score_frames(model, frames, on_frame=keep, cells_per_step=2,
                 near_iou=recipe.near_iou if recipe.near_per_frame else None)
    crops = false_window_crops(frames, fired, win, win, recipe.hard_per_frame, seed=seed)
    if recipe.near_per_frame:
        crops = np.concatenate([crops, window_crops(frames, near, win, win, recipe.near_per_frame, seed=seed)])
    return crops, sum(len(w) for w in fired)


@dataclass
class KeyframeCrops:
    """The crops :func:`keyframe_crops` cut: ``crops`` (labels 1 / 0; groups ``keyframes/CLIP``
    for the positives) and what they were."""

    crops: CropSet
    positives: int
    background: int
    hard: int
    fired: int  # windows above hard_threshold touching no annotated box, before the per-frame limit

    def counts(self) -> dict[str, int]:
        return {"positives": self.positives, "background": self.background, "hard_negatives": self.hard,
                "false_windows": self.fired}


def keyframe_crops(frames: Sequence[AnnotatedFrame], recipe: KeyframeRecipe = KeyframeRecipe(),
                   model: Model | None = None, config: FeatureConfig | None = None) -> KeyframeCrops:
    """Positives, background and one round of hard negatives (mined with ``model``, default the
    bundled one) of ``frames`` (module docstring) for square windows of ``config`` (default
    ``model``'s)."""
    model = model if model is not None else load_model(None)
    cfg = config if config is not None else model.config
    if cfg.win_w != cfg.win_h:
        raise ValueError(f"keyframe_crops: the main model's windows are square, got {cfg.win_w}x{cfg.win_h}")
    win = cfg.win_w
    parts, groups = [], []
    for i, f in enumerate(frames):
        p = positive_crops([f], win, win, (0.0, recipe.max_aspect), margin=recipe.margin, min_width=0.0,
                           jitter=recipe.jitter, seed=recipe.seed + i)
        parts.append(p)
        groups += [f"keyframes/{f.clip}"] * len(p)
    pos = _labelled(np.concatenate(parts) if parts else np.zeros((0, win, win, 3), np.uint8), 1, groups)
    bg = background_crops(frames, win, win, recipe.background, seed=recipe.seed)
    hard, fired = mine_hard(frames, model, recipe, win, recipe.seed)
    neg = _labelled(np.concatenate([bg, hard]), 0, ["keyframes/background"] * len(bg) + ["keyframes/hard"] * len(hard))
    return KeyframeCrops(CropSet.concat(pos, neg), len(pos), len(bg), len(hard), fired)


def train_keyframe_model(data: Path, config: FeatureConfig, frames: Sequence[AnnotatedFrame],
                         recipe: KeyframeRecipe = KeyframeRecipe(), mining_model: Model | None = None,
                         log: Callable[[str], None] = print, previous: Sequence[Model] = (),
                         **train_args: Any) -> Model:
    """A main model trained on the data set's crops under ``data`` and :func:`keyframe_crops`
    of ``frames`` (hard negatives mined with ``mining_model``, default the bundled one), then
    ``recipe.hard_rounds - 1`` more times, each with the false windows of the model the round
    before trained added (:func:`mine_hard`). ``previous``: models of the first rounds already
    trained on the same frames and recipe (they are not trained again, their false windows
    are mined). ``train_args``: :func:`fastdet.train.fit.train`'s options (augmentation,
    ``C``, ``seed``...; ``split`` default ``"none"``). The model's metadata records the clips,
    frames and counts."""
    t0 = time.perf_counter()
    kc = keyframe_crops(frames, recipe, mining_model, config)
    clips = sorted({f.clip for f in frames})
    log(f"keyframes of {', '.join(clips) or 'no clip'}: {len(frames)} frames, {kc.positives} positives, "
        f"{kc.background} background, {kc.hard} hard negatives of {kc.fired} false windows "
        f"({time.perf_counter() - t0:.1f} s)")
    train_args.setdefault("split", "none")
    train_args.setdefault("progress", False)
    crops, hard, fired = kc.crops, [kc.hard], [kc.fired]
    model: Model | None = None
    for r in range(recipe.hard_rounds):
        if r:
            assert model is not None
            more, n = mine_hard(frames, model, recipe, config.win_w, recipe.seed + r)
            crops = CropSet.concat(crops, _labelled(more, 0, f"keyframes/hard{r + 1}"))
            hard.append(len(more))
            fired.append(n)
            log(f"round {r + 1}: {len(more)} hard negatives of {n} false windows ({time.perf_counter() - t0:.1f} s)")
        if r < len(previous):
            model = previous[r]
            continue
        model, _ = train(data, config, extra_crops=crops, log=log, **train_args)
        if model is None:
            raise ValueError("train_keyframe_model: refit=False gives no model")
    assert model is not None
    model.metadata["training"]["keyframes"] = {"clips": clips, "frames": len(frames), "recipe": recipe.to_dict(),
                                               **kc.counts(), "hard_negatives": hard, "false_windows": fired}
    return model

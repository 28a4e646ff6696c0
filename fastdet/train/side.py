"""A camera's side-view component (``python -m fastdet adapt``): a linear model of wide windows
(64x32) for the vehicles a square window does not fit -- cars seen side-on or obliquely in
crossing and turning traffic, buses and trucks alongside --, fitted on the camera's own
labelled frames alone and carried in its model file (:attr:`fastdet.model.Model.side`).

The component learns them from the camera's wide targets (what it scored: docs/training.md, "A
side-view component for the camera"):

- positives: every target at least :attr:`~fastdet.config.adapt.AdaptConfig.side_aspect` as wide
  as tall and :data:`MIN_WIDTH` px wide, cut at the window's aspect with jittered copies
  (:func:`~fastdet.train.keyframes.positive_crops`), and their mirror images;
- negatives: random 2:1 windows of the background (touching no labelled box), then one round of
  hard negatives: the windows the first fit fires on that touch no labelled box, at the bands
  the video pipeline searches (:func:`hard_negatives`), on at most ``mining_frames`` of the
  frames (the main model's later mining rounds' setting), spread evenly;
- a logistic regression on the main model's features of that window, the two classes weighted
  equally (the negatives outnumber the positives many times).

Its decision offset -- or leaving it out -- is chosen on the frames kept aside
(:func:`fastdet.train.operating_point.choose_side_offset`).
"""
from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..boxes import intersection
from ..config import FeatureConfig, SearchConfig
from ..config.adapt import AdaptConfig
from ..detect import Detector
from ..detections import FIRST_COMPONENT_PART
from ..labels.load import load_pictures
from ..labels.picture import AnnotatedPicture
from ..model import Model
from .adapt import spread, ticking
from .dataset import CropSet
from .fit import features_in_chunks, fit_classifier
from .keyframes import aspect_of, background_crops, positive_crops, window_crops
from .pictures import as_frame, crop_set

#: the side-view window's height, in pixels at scale 1 (its width is the main model's window)
WINDOW_HEIGHT = 32
#: a target narrower than this (pixels) is not a side-view positive: scaled up to 64 px it is a blur
MIN_WIDTH = 32.0


def side_config(main: FeatureConfig) -> FeatureConfig:
    """The component's features: the main model's at a window ``main.window`` wide and
    :data:`WINDOW_HEIGHT` tall."""
    return replace(main, window_height=WINDOW_HEIGHT)


def wide_targets(targets: np.ndarray, aspect: float) -> np.ndarray:
    """``(N, 4)`` boxes of ``targets`` at least ``aspect`` as wide as tall and :data:`MIN_WIDTH` wide."""
    t = np.asarray(targets, np.float64).reshape(-1, 4)
    return t[(aspect_of(t) >= aspect) & (t[:, 2] - t[:, 0] >= MIN_WIDTH)]


def count_wide(pictures: Sequence[AnnotatedPicture], aspect: float) -> int:
    """How many side-view positives ``pictures`` hold (:func:`wide_targets`)."""
    return sum(len(wide_targets(p.targets, aspect)) for p in pictures)


def side_crops(pictures: Sequence[AnnotatedPicture], config: FeatureConfig, adapt: AdaptConfig,
               progress: bool = True) -> CropSet:
    """The component's first crops, ``(N, 32, 64, 3) uint8`` (module docstring): positives
    (``adapt.side_jitter`` jittered copies each, then every positive mirrored) and
    ``adapt.side_negatives`` background windows a complete picture."""
    pos: list[np.ndarray] = []
    neg: list[np.ndarray] = []
    gpos: list[str] = []
    gneg: list[str] = []
    rng = np.random.default_rng(adapt.seed)
    for pic, image in ticking(pictures, "side-view crops", progress):
        f = as_frame(pic, image)
        s = int(rng.integers(2**31))
        wide = wide_targets(pic.targets, adapt.side_aspect)
        if len(wide):
            p = positive_crops([replace(f, targets=wide)], config.win_w, config.win_h, jitter=adapt.side_jitter,
                               seed=s)
            pos += [p, p[:, :, ::-1]]
            gpos += [pic.camera] * (2 * len(p))
        if pic.complete and adapt.side_negatives:
            n = background_crops([f], config.win_w, config.win_h, adapt.side_negatives, seed=s)
            neg.append(n)
            gneg += [pic.camera] * len(n)
    return CropSet.concat(crop_set(pos, 1, gpos, config.win_h, config.win_w),
                          crop_set(neg, 0, gneg, config.win_h, config.win_w))


def _fit(crops: CropSet, config: FeatureConfig, adapt: AdaptConfig, metadata: dict[str, Any]) -> Model:
    """Logistic regression on ``crops``, the classes weighted equally (each class's weights sum to
    half the rows)."""
    x = features_in_chunks(crops.images, config, progress=False)
    y = crops.labels
    n_pos = int(y.sum())
    if not 0 < n_pos < len(y):
        raise ValueError("side-view fit: both positive and negative crops are needed")
    w = np.where(y == 1, len(y) / (2.0 * n_pos), len(y) / (2.0 * (len(y) - n_pos)))
    scaler, clf = fit_classifier(x, y, "logreg", adapt.side_C, adapt.seed, in_place=True, sample_weight=w)
    return Model(config=config, coef=clf.coef_.ravel(), intercept=float(clf.intercept_[0]), mean=scaler.mean_,
                 scale=scaler.scale_, classifier="logreg", metadata=metadata)


def hard_negatives(model: Model, search: SearchConfig, pictures: Sequence[AnnotatedPicture], per_picture: int,
                   frames: Iterable[tuple[AnnotatedPicture, np.ndarray]] | None = None) -> CropSet:
    """``(N, 32, 64, 3) uint8`` crops: on each picture, the ``per_picture`` highest-scoring
    positive windows of ``model``'s side-view component at ``search`` (a video's bands, as the
    pipeline searches them) that touch no labelled box (target or ignore region). ``frames``:
    the pictures with their pixels, when already decoded."""
    assert model.side is not None
    detector = Detector(model, search)
    cfg = model.side.config
    crops: list[np.ndarray] = []
    groups: list[str] = []
    for pic, image in (frames if frames is not None else load_pictures(pictures)):
        f = as_frame(pic, image)
        w = detector.detect(image)
        w = w[w.part == FIRST_COMPONENT_PART]
        boxes = f.boxes  # targets and ignore regions
        if len(boxes):
            w = w[~np.any(intersection(w.boxes.astype(np.float64), boxes) > 0, axis=1)]
        top = np.argsort(-w.scores, kind="stable")[:per_picture]
        c = window_crops([f], [w.boxes[top]], cfg.win_w, cfg.win_h)
        crops.append(c)
        groups += [pic.camera] * len(c)
    return crop_set(crops, 0, groups, cfg.win_h, cfg.win_w)


def fit_side_model(pictures: Sequence[AnnotatedPicture], main: Model, search: SearchConfig, adapt: AdaptConfig,
                   progress: bool = True) -> tuple[Model | None, dict[str, Any]]:
    """The camera's side-view component from its labelled ``pictures`` (module docstring), of the
    features of ``main`` (a logistic-regression model) at the wide window, its hard negatives
    mined at ``search`` (the video's bands at the camera's horizon); with its report
    (``vehicles``: side-view targets, ``positives`` / ``negatives`` / ``hard_negatives``: crops,
    ``seconds``). ``(None, report)`` when the pictures hold fewer than
    ``adapt.side_min_vehicles`` side-view targets (nothing to learn the view from) or ``main`` is
    not a logistic regression (the scores would not compare); the report's ``skipped`` says which."""
    t0 = time.perf_counter()
    vehicles = count_wide(pictures, adapt.side_aspect)
    report: dict[str, Any] = {"vehicles": vehicles}
    if main.classifier != "logreg":
        return None, {**report, "skipped": f"the main model is a {main.classifier} model, not a logistic regression"}
    if vehicles < adapt.side_min_vehicles:
        return None, {**report, "skipped": f"{vehicles} labelled vehicles of {adapt.side_aspect:g}:1 and wider to "
                                           f"fit it on, fewer than {adapt.side_min_vehicles}"}
    config = side_config(main.config)
    crops = side_crops(pictures, config, adapt, progress)
    if not (crops.labels == 0).any():
        return None, {**report, "skipped": "no background to learn from (every labelled frame is partial, or "
                                           "side_negatives is 0)"}
    report.update(positives=int(crops.labels.sum()), negatives=int((crops.labels == 0).sum()))
    meta = {"trained_on": "the camera's labelled frames (fastdet adapt): its side-view targets", "fit": report}
    model = _fit(crops, config, adapt, meta)
    mined = spread([p for p in pictures if p.complete], adapt.mining_frames)
    hard = hard_negatives(replace(main, side=model), search, mined, adapt.side_hard,
                          ticking(mined, "side-view hard negatives", progress))
    report["hard_negatives"] = len(hard)
    if len(hard):
        model = _fit(CropSet.concat(crops, hard), config, adapt, meta)
    report["seconds"] = round(time.perf_counter() - t0, 2)
    return model, report

"""Training a model: features of crops → StandardScaler → LinearSVC / LogisticRegression.

:func:`train` reports accuracy, precision, recall, F1 and the confusion matrix on a random
80/20 split and on a leak-free *sequence* split (every folder cut into contiguous time
blocks, see :mod:`fastdet.train.dataset`), then refits on all the data. Hard negatives and
flip augmentation only ever join the *training* part of a split, so the test figures stay
comparable; so do the augmented copies of :mod:`fastdet.train.augment` (crops cut by the
image border, ``truncate``; compression artefacts, ``reencode``): a split adds only the
copies made from its training crops. Deterministic for a given seed.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.preprocessing import StandardScaler
from sklearn.svm import LinearSVC
from tqdm import tqdm

from ..config import FeatureConfig
from ..features import extract_features
from ..model import Model
from .augment import JPEG_QUALITY, MAX_KEEP, MIN_KEEP, augmented_copies
from .dataset import CropSet, check_splits, load_crops, load_folder, random_split, sequence_split

DEFAULT_C = {"linearsvc": 1e-3, "logreg": 3e-2}


def features_in_chunks(images: np.ndarray, config: FeatureConfig, progress: bool, desc: str = "features",
                       chunk: int = 2048, out: np.ndarray | None = None) -> np.ndarray:
    """``(N, n_features) float64`` window features of ``(N, h, w, 3) uint8`` crops, computed
    ``chunk`` crops at a time; into ``out`` (rows of a bigger matrix, float64 or float32: each
    chunk is computed in float64 and rounded into it) when given."""
    if out is None:
        out = np.empty((len(images), config.n_features), np.float64)
    elif out.shape != (len(images), config.n_features):
        raise ValueError(f"features_in_chunks: out is {out.shape}, want {(len(images), config.n_features)}")
    starts = range(0, len(images), chunk)
    if progress:
        starts = tqdm(starts, desc=desc, unit="chunk", leave=False)
    for s in starts:
        out[s: s + chunk] = extract_features(images[s: s + chunk], config)
    return out


def fit_scaler(x: np.ndarray, sample_weight: np.ndarray | None = None, chunk: int = 4096) -> StandardScaler:
    """A StandardScaler fitted to ``x`` (``(N, F)``, rows of weight ``sample_weight``) ``chunk``
    rows at a time (``partial_fit``): its mean and variance as one ``fit`` gives them (up to
    rounding), without the float64 temporaries of the size of ``x`` that ``fit`` makes (a
    centred copy, and with weights a mask and a second copy: three times the memory of a
    float32 ``x``)."""
    scaler = StandardScaler()
    for s in range(0, len(x), chunk):
        w = None if sample_weight is None else sample_weight[s: s + chunk]
        scaler.partial_fit(x[s: s + chunk], sample_weight=w)
    return scaler


def fit_classifier(x: np.ndarray, y: np.ndarray, classifier: str, C: float, seed: int, in_place: bool = False,
                   sample_weight: np.ndarray | None = None):
    """StandardScaler + classifier; returns ``(scaler, clf)``. ``in_place``: standardise ``x``
    itself (a float64 or float32 array the caller no longer needs as it was) instead of a
    copy: half the memory of a large training set. ``sample_weight``: ``(N,)`` weight of each
    row, in the scaler's mean and variance and in the classifier's loss alike: a row of weight
    ``w`` counts as ``w`` copies of it, without the memory of the copies."""
    scaler = fit_scaler(x, sample_weight)
    xs = scaler.transform(x, copy=not in_place)
    if classifier == "linearsvc":
        clf = LinearSVC(C=C, dual=False, random_state=seed, max_iter=5000)
    else:
        clf = LogisticRegression(C=C, max_iter=2000, random_state=seed)
    clf.fit(xs, y, sample_weight=sample_weight)
    return scaler, clf


def metrics(y_true: np.ndarray, y_pred: np.ndarray) -> dict[str, Any]:
    from sklearn.metrics import (
        accuracy_score,
        confusion_matrix,
        f1_score,
        precision_score,
        recall_score,
    )

    return {
        "accuracy": float(accuracy_score(y_true, y_pred)),
        "precision": float(precision_score(y_true, y_pred, zero_division=0)),
        "recall": float(recall_score(y_true, y_pred, zero_division=0)),
        "f1": float(f1_score(y_true, y_pred, zero_division=0)),
        # rows: true non-vehicle, vehicle; columns: predicted non-vehicle, vehicle
        "confusion": confusion_matrix(y_true, y_pred, labels=[0, 1]).tolist(),
        "n_test": int(len(y_true)),
    }


def format_metrics(name: str, m: dict[str, Any]) -> str:
    (tn, fp), (fn, tp) = m["confusion"]
    return (f"{name:>9} split: accuracy {m['accuracy']:.4f}  precision {m['precision']:.4f}  "
            f"recall {m['recall']:.4f}  F1 {m['f1']:.4f}  (test n={m['n_test']})\n"
            f"{'':>17}confusion [[TN {tn:5d}  FP {fp:5d}]  [FN {fn:5d}  TP {tp:5d}]]")


def _flip(images: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(images[:, :, ::-1])


def row_bands(crops, top: int, height: int):
    """Wide-window training set: vehicles' rows ``[top, top + height)``; every non-vehicle
    crop gives its top, middle-window and bottom row bands (three negatives, same group and
    time position, so the sequence split keeps them together)."""
    pos = np.flatnonzero(crops.labels == 1)
    neg = np.flatnonzero(crops.labels == 0)
    parts = [CropSet(np.ascontiguousarray(crops.images[pos, top: top + height]), crops.labels[pos],
                     crops.groups[pos], crops.order[pos])]
    for off in sorted({0, top, crops.images.shape[1] - height}):
        parts.append(CropSet(np.ascontiguousarray(crops.images[neg, off: off + height]), crops.labels[neg],
                             crops.groups[neg], crops.order[neg]))
    out = parts[0]
    for p in parts[1:]:
        out = CropSet.concat(out, p)
    return out


def fit_to_window(crops, config: FeatureConfig, top: int):
    """Extra negatives to the config's window: a crop of the window's own size is kept, a
    64x64 crop gives its rows ``[top, top + win_h)``, anything else is resized."""
    h, w = crops.images.shape[1:3]
    if (h, w) == (config.win_h, config.win_w):
        return crops
    if w == config.win_w and h >= top + config.win_h:
        return CropSet(np.ascontiguousarray(crops.images[:, top: top + config.win_h]), crops.labels,
                       crops.groups, crops.order)
    imgs = np.stack([cv2.resize(im, (config.win_w, config.win_h), interpolation=cv2.INTER_AREA)
                     for im in crops.images])
    return CropSet(imgs, crops.labels, crops.groups, crops.order)


def train(data: Path, config: FeatureConfig, classifier: str = "logreg", C: float | None = None,
          split: str = "both", seed: int = 0, negatives: list[Path] | None = None, flip: bool = True,
          max_per_folder: int | None = None, refit: bool = True, progress: bool = True,
          window_top: int | None = None, positives: list[Path] | None = None, truncate: float = 0.0,
          truncate_negatives: bool = True, reencode: float = 0.0, jpeg_quality: tuple[int, int] = JPEG_QUALITY,
          truncate_keep: tuple[float, float] = (MIN_KEEP, MAX_KEEP), extra_crops: CropSet | None = None,
          crop_size: int = 64, extra_weight: float = 1.0,
          dtype: type[np.floating[Any]] = np.float64, log=print):
    """Train and evaluate; returns ``(model or None, report dict)``.

    ``split``: ``"both"``, ``"random"``, ``"sequence"`` or ``"none"`` (no held-out evaluation).
    ``negatives`` / ``positives``: folders of extra crops; ``extra_crops``: more extra crops
    in memory, labelled (e.g. cut from annotated video frames,
    :mod:`fastdet.train.keyframe_model`), of the config's window size. Extra crops join every
    training part, never a test part; extra vehicles are mirrored as the data set's crops.
    ``extra_weight``: the sample weight of every ``extra_crops`` row and its mirror image (the
    data set's crops and the folders' weigh 1): a camera's few crops count as that many copies.
    ``dtype``: the features' type in the fit (``np.float32``: half the memory of float64; the
    model's arrays are float64 either way).

    ``truncate`` / ``reencode``: fractions of the crops that also join the training parts as
    truncated / re-encoded copies (:func:`fastdet.train.augment.augmented_copies`; truncated
    copies of as many non-vehicles unless ``truncate_negatives`` is false; ``truncate_keep``: the
    range of the fraction of columns a truncated copy keeps).

    For a wide-window ``config`` (``window_height`` set), ``window_top`` is the first row of
    the 64x64 crops that the window covers (default: centred).

    ``crop_size``: the data set's crops are resized to ``crop_size`` x ``crop_size`` first
    (``cv2.INTER_AREA``; 64: as they are): a small-window model learns from crops downscaled
    to its window."""
    if split not in ("both", "random", "sequence", "none"):
        raise ValueError(f"split must be 'both', 'random', 'sequence' or 'none', got {split!r}")
    if not (math.isfinite(extra_weight) and extra_weight > 0):
        raise ValueError(f"extra_weight must be a finite number > 0, got {extra_weight!r}")
    if extra_crops is not None and extra_crops.images.shape[1:3] != (config.win_h, config.win_w):
        raise ValueError(f"extra_crops are {extra_crops.images.shape[2]}x{extra_crops.images.shape[1]}, "
                         f"the window is {config.win_w}x{config.win_h}")
    C = DEFAULT_C[classifier] if C is None else C
    t0 = time.perf_counter()
    crops = load_crops(data, size=crop_size, progress=progress, max_per_folder=max_per_folder)
    top = (crops.images.shape[1] - config.win_h) // 2 if window_top is None else window_top
    if config.win_h != crops.images.shape[1]:
        crops = row_bands(crops, top, config.win_h)
    extra = None  # extra crops: hard negatives (label 0) and extra positives (label 1)
    for folder, label in [(nd, 0) for nd in negatives or []] + [(pd, 1) for pd in positives or []]:
        part = fit_to_window(load_folder(folder, label, None, size=None, progress=progress), config, top)
        extra = part if extra is None else CropSet.concat(extra, part)
    # the weight of every extra row (the folders' crops 1, ``extra_crops`` ``extra_weight``), or None: all 1
    w_extra = None
    if extra_crops is not None and len(extra_crops):
        if extra_weight != 1.0:
            w_extra = np.r_[np.ones(0 if extra is None else len(extra)), np.full(len(extra_crops), float(extra_weight))]
        extra = extra_crops if extra is None else CropSet.concat(extra, extra_crops)
    check_splits(crops.labels, crops.groups, crops.order, split, seed)  # before any feature is computed
    n_pos, n_neg = int(crops.labels.sum()), int((crops.labels == 0).sum())
    n_hard = 0 if extra is None else int((extra.labels == 0).sum())
    n_extra = 0 if extra is None else int((extra.labels == 1).sum())
    log(f"data: {n_pos} vehicles, {n_neg} non-vehicles"
        + (f", {n_hard} hard negatives" if n_hard else "") + (f", {n_extra} extra positives" if n_extra else "")
        + f" ({time.perf_counter() - t0:.1f} s)")

    def training_part(idx):
        parts = [(x[idx], crops.labels[idx], None)]
        if x_flip is not None:
            parts.append((x_flip[idx], crops.labels[idx], None))
        if x_aug is not None:
            a = aug.in_training(idx)
            parts.append((x_aug[a], aug.labels[a], None))
        if x_extra is not None:
            parts.append((x_extra, extra.labels, w_extra))
            if x_extra_flip is not None:
                parts.append((x_extra_flip, extra.labels[extra.labels == 1],
                              None if w_extra is None else w_extra[extra.labels == 1]))
        xs, ys, ws = zip(*parts)
        sw = None if w_extra is None else np.concatenate([np.ones(len(v)) if u is None else u
                                                          for v, u in zip(ys, ws)])
        return np.concatenate(xs), np.concatenate(ys), sw

    aug = augmented_copies(crops.images, crops.labels, seed, truncate, truncate_negatives, reencode, jpeg_quality,
                           truncate_keep)
    report: dict[str, Any] = {"C": C, "classifier": classifier, "seed": seed, "flip": flip, "window_top": top,
                              "crop_size": crop_size,
                              "augment": {"truncate": truncate, "truncate_negatives": truncate_negatives,
                                          "truncate_keep": list(truncate_keep),
                                          "reencode": reencode, "jpeg_quality": list(jpeg_quality),
                                          "copies": len(aug)},
                              "data": {"vehicles": n_pos, "non_vehicles": n_neg,
                                       "hard_negatives": n_hard, "extra_positives": n_extra}}
    if w_extra is not None:
        report["extra_weight"] = extra_weight
    if split == "none" and refit:
        return _fit_once(crops, extra, w_extra, aug, config, flip, classifier, C, seed, progress, t0, log, dtype,
                         report_base=report)

    def feats(images: np.ndarray, desc: str = "features") -> np.ndarray:
        return features_in_chunks(images, config, progress, desc, out=np.empty((len(images), config.n_features),
                                                                                  dtype))

    x = feats(crops.images)
    x_flip = feats(_flip(crops.images), "flipped") if flip else None
    x_extra = feats(extra.images, "extra crops") if extra is not None else None
    # extra positives are mirrored like the data set's crops; hard negatives are kept as mined
    x_extra_flip = None
    if extra is not None and flip and n_extra:
        x_extra_flip = feats(_flip(extra.images[extra.labels == 1]), "flipped")
    x_aug = feats(aug.images, "augmented") if len(aug) else None
    if len(aug):
        log(f"augmented copies: {len(aug)} ({int(aug.labels.sum())} vehicles; truncate {truncate:g}"
            f"{'' if truncate_negatives else ' of vehicles only'}, reencode {reencode:g}) "
            f"({time.perf_counter() - t0:.1f} s)")
    log(f"features: {config.n_features} per crop ({time.perf_counter() - t0:.1f} s)")
    splits = {"random": lambda: random_split(crops.labels, seed),
              "sequence": lambda: sequence_split(crops.groups, crops.order, seed)}
    for name in {"both": ("random", "sequence"), "none": ()}.get(split, (split,)):
        tr, te = splits[name]()
        xt, yt, wt = training_part(tr)
        scaler, clf = fit_classifier(xt, yt, classifier, C, seed, in_place=True, sample_weight=wt)
        del xt
        m = metrics(crops.labels[te], clf.predict(scaler.transform(x[te])))
        report[f"{name}_split"] = m
        log(format_metrics(name, m) + f"  ({time.perf_counter() - t0:.1f} s)")
    if not refit:
        return None, report
    xt, yt, wt = training_part(np.arange(len(crops)))
    return _final_fit(xt, yt, wt, config, classifier, C, seed, report, t0, log)


def _final_fit(xt: np.ndarray, yt: np.ndarray, wt: np.ndarray | None, config: FeatureConfig, classifier: str,
               C: float, seed: int, report: dict[str, Any], t0: float, log: Any) -> tuple[Model, dict[str, Any]]:
    """The model fitted on every training row ``xt`` (standardised in place; ``wt``: the rows'
    sample weights, None: all 1), its training accuracy (unweighted) in ``report``, which
    becomes its ``metadata["training"]``."""
    scaler, clf = fit_classifier(xt, yt, classifier, C, seed, in_place=True, sample_weight=wt)
    report["train_accuracy"] = float((clf.predict(xt) == yt).mean())
    model = Model(config=config, coef=clf.coef_.ravel(), intercept=float(clf.intercept_[0]),
                  mean=scaler.mean_, scale=scaler.scale_, classifier=classifier,
                  metadata={"training": report})
    log(f"final fit on {len(yt)} crops: training accuracy {report['train_accuracy']:.4f} "
        f"({time.perf_counter() - t0:.1f} s)")
    return model, report


def _fit_once(crops: CropSet, extra: CropSet | None, w_extra: np.ndarray | None, aug: Any, config: FeatureConfig,
              flip: bool, classifier: str, C: float, seed: int, progress: bool, t0: float, log: Any,
              dtype: type[np.floating[Any]], report_base: dict[str, Any]):
    """:func:`train` with ``split="none"``: no held-out evaluation, so every training row's
    features go straight into one preallocated ``dtype`` matrix (the crops, their mirror images,
    the augmented copies, the extra crops and the extra vehicles' mirror images) instead of into
    parts that are then joined: half the peak memory of a large training set. ``w_extra``: the
    extra crops' sample weights (None: all 1)."""
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, str]] = [
        (crops.images, crops.labels, None, "features")]
    if flip:
        parts.append((_flip(crops.images), crops.labels, None, "flipped"))
    if len(aug):
        parts.append((aug.images, aug.labels, None, "augmented"))
    if extra is not None and len(extra):
        parts.append((extra.images, extra.labels, w_extra, "extra crops"))
        pos = extra.labels == 1
        if flip and pos.any():
            parts.append((_flip(extra.images[pos]), extra.labels[pos], None if w_extra is None else w_extra[pos],
                          "flipped"))
    n = sum(len(p[0]) for p in parts)
    xt = np.empty((n, config.n_features), dtype)
    yt = np.empty(n, np.int64)
    wt = None if w_extra is None else np.ones(n)
    row = 0
    for images, labels, weights, desc in parts:
        features_in_chunks(images, config, progress, desc, out=xt[row: row + len(images)])
        yt[row: row + len(images)] = labels
        if wt is not None and weights is not None:
            wt[row: row + len(images)] = weights
        row += len(images)
    if len(aug):
        log(f"augmented copies: {len(aug)} ({int(aug.labels.sum())} vehicles) ({time.perf_counter() - t0:.1f} s)")
    log(f"features: {config.n_features} per crop, {n} training rows ({time.perf_counter() - t0:.1f} s)")
    return _final_fit(xt, yt, wt, config, classifier, C, seed, dict(report_base), t0, log)

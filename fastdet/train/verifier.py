"""Training the box verifier (:mod:`fastdet.detect.verifier`): the single-picture search's
first stage is run on labelled pictures, each of its refined boxes is labelled against the
pictures' boxes, and a logistic regression learns which boxes are vehicles.

- :func:`label_boxes`: 1 for a box that matches a labelled vehicle (IoU >= 0.5), 0 for one
  that overlaps none (IoU < 0.3) and lies mostly outside every ignore region, -1 (left out)
  otherwise. Partial pictures (``complete=False``) give positives only.
- :func:`collect`: the first stage's refined boxes, their verifier inputs and labels on every
  picture.
- :func:`fit_verifier`: negatives thinned to at most ``max_negatives`` a camera (so that a
  camera whose picture search fires everywhere does not outweigh the others), a logistic
  regression on standardised inputs with balanced classes, and the operating point by the
  cascade rule on cameras held out of the fit (``folds`` groups of cameras): the largest
  threshold at which the verifier keeps ``keep_fraction`` of the first stage's matching boxes.
"""
from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..boxes import iou, overlap_fraction
from ..detect.verifier import VERIFIER_CONTEXTS, VERIFIER_FEATURES, BoxVerifier, verifier_inputs
from ..detections import Detections
from ..errors import DataError, ModelError
from ..labels.load import load_pictures
from ..labels.picture import AnnotatedPicture
from ..model import read_npz, write_npz

#: a box matching a labelled vehicle at this IoU is a positive
POSITIVE_IOU = 0.5
#: a box overlapping every labelled vehicle less than this is a negative (between: left out)
NEGATIVE_IOU = 0.3
#: a box with at least this fraction of its area inside an ignore region is left out
IGNORE_OVERLAP = 0.5
#: the layout of :func:`save_candidates`' files
CANDIDATES_VERSION = 1


def label_boxes(boxes: np.ndarray, targets: np.ndarray, ignores: np.ndarray, complete: bool = True) -> np.ndarray:
    """``(N,) int8`` labels of ``boxes (N, 4)`` against a picture's ``targets (T, 4)`` and
    ``ignores (G, 4)`` (module docstring); a partial picture's boxes are 1 or -1."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    n = len(b)
    best = iou(b, targets).max(axis=1) if len(targets) and n else np.zeros(n)
    ign = overlap_fraction(b, ignores).max(axis=1) if len(ignores) and n else np.zeros(n)
    y = np.full(n, -1, np.int8)
    y[best >= POSITIVE_IOU] = 1
    if complete:
        y[(best < NEGATIVE_IOU) & (ign < IGNORE_OVERLAP)] = 0
    return y


@dataclass(frozen=True, eq=False)
class Candidates:
    """The first stage's boxes on a set of pictures: ``x (N, F) float32`` verifier inputs
    (appearance, then the first stage's decision value), ``y (N,) int8`` labels
    (:func:`label_boxes`), ``camera (N,)`` str, ``picture (N,)`` index into the pictures."""

    x: np.ndarray
    y: np.ndarray
    camera: np.ndarray
    picture: np.ndarray

    def __len__(self) -> int:
        return len(self.y)


def collect(pictures: Sequence[AnnotatedPicture], first_stage: Callable[[np.ndarray], Detections],
            tick: Callable[[], None] | None = None) -> Candidates:
    """Run ``first_stage`` (a picture's refined boxes with their decision values:
    ``PictureDetector(config=PictureSearch(verify=False)).detect``) on every picture and keep
    each box's inputs and label. ``tick`` is called after each picture (progress)."""
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    cams: list[str] = []
    idx: list[np.ndarray] = []
    for i, (pic, image) in enumerate(load_pictures(pictures)):  # in the pictures' order
        d = first_stage(image)
        if len(d):
            xs.append(verifier_inputs(image, d.boxes, d.scores).astype(np.float32))
            ys.append(label_boxes(d.boxes, pic.targets, pic.ignores, pic.complete))
            cams.extend([pic.camera] * len(d))
            idx.append(np.full(len(d), i, np.int64))
        if tick is not None:
            tick()
    n_f = len(VERIFIER_CONTEXTS) * VERIFIER_FEATURES.n_features + 1
    return Candidates(np.concatenate(xs) if xs else np.zeros((0, n_f), np.float32),
                      np.concatenate(ys) if ys else np.zeros(0, np.int8),
                      np.array(cams, dtype=str), np.concatenate(idx) if idx else np.zeros(0, np.int64))


def save_candidates(path: str | os.PathLike, c: Candidates, key: dict[str, Any]) -> None:
    """Keep ``c`` in ``path`` (``.npz``, atomically) with ``key`` (what made them: the first
    stage's settings and the pictures), for :func:`load_candidates`."""
    names, codes = np.unique(c.camera, return_inverse=True)
    write_npz(path, {"x": c.x, "y": c.y, "camera": codes.astype(np.int64), "picture": c.picture},
              {"format_version": CANDIDATES_VERSION, "key": key, "cameras": names.tolist()})


#: the largest array a first-stage cache may hold: the bundled verifier's (2,170 frames) is
#: 105,527 x 3,913 float32, 1.65 GB, far past a model file's budget (``MAX_ARRAY_BYTES``), which
#: made every full-size cache unreadable (written, then recomputed on each run)
MAX_CANDIDATES_BYTES = 16 * 2**30


def load_candidates(path: str | os.PathLike, key: dict[str, Any]) -> Candidates | None:
    """The candidates :func:`save_candidates` kept in ``path`` when they were made with ``key``;
    ``None`` when there is no such file or it was made otherwise."""
    p = Path(path)
    if not p.is_file():
        return None
    try:
        arrays, meta = read_npz(p, ("x", "y", "camera", "picture", "metadata"), "candidates file",
                                CANDIDATES_VERSION, max_array_bytes=MAX_CANDIDATES_BYTES)
    except ModelError:
        return None
    if meta.get("key") != key:
        return None
    names = np.array(meta["cameras"], dtype=str)
    return Candidates(arrays["x"], arrays["y"].astype(np.int8), names[arrays["camera"]], arrays["picture"])


@dataclass(frozen=True)
class VerifierRecipe:
    """How :func:`fit_verifier` fits: ``C`` (inverse regularisation), ``max_negatives`` a
    camera, ``keep_fraction`` (the cascade rule), ``folds`` (groups of cameras held out for the
    operating point), ``score_input`` (the first stage's decision value among the inputs),
    ``seed``."""

    C: float = 0.01
    max_negatives: int = 2500
    keep_fraction: float = 0.9
    folds: int = 5
    score_input: bool = True
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.C > 0:
            raise ValueError(f"C must be positive, got {self.C!r}")
        if self.max_negatives < 1:
            raise ValueError(f"max_negatives must be >= 1, got {self.max_negatives!r}")
        if not 0 < self.keep_fraction <= 1:
            raise ValueError(f"keep_fraction must be in (0, 1], got {self.keep_fraction!r}")
        if self.folds < 2:
            raise ValueError(f"folds must be >= 2, got {self.folds!r}")


def _thinned(c: Candidates, recipe: VerifierRecipe, rng: np.random.Generator) -> np.ndarray:
    """Indices of the labelled rows, negatives thinned to ``max_negatives`` a camera."""
    out = []
    for cam in np.unique(c.camera):
        i = np.flatnonzero((c.camera == cam) & (c.y >= 0))
        pos, neg = i[c.y[i] == 1], i[c.y[i] == 0]
        if len(neg) > recipe.max_negatives:
            neg = np.sort(rng.choice(neg, recipe.max_negatives, replace=False))
        out += [pos, neg]
    return np.concatenate(out) if out else np.zeros(0, np.int64)


def _fit(x: np.ndarray, y: np.ndarray, C: float) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    from sklearn.linear_model import LogisticRegression

    mean = x.mean(axis=0, dtype=np.float64)
    scale = x.std(axis=0, dtype=np.float64)
    scale = np.where(scale > 1e-6, scale, 1.0)
    m = LogisticRegression(C=C, class_weight="balanced", max_iter=500).fit((x - mean) / scale, y)
    return m.coef_[0].astype(np.float64), float(m.intercept_[0]), mean, scale


def operating_point(held_out: np.ndarray, y: np.ndarray, keep_fraction: float) -> float:
    """The largest threshold at which ``held_out`` decision values (of boxes labelled ``y``)
    keep at least ``keep_fraction`` of the positives: a threshold just below the
    ``ceil((1 - keep_fraction) * P)``-th lowest positive's value."""
    pos = np.sort(held_out[y == 1])
    if len(pos) == 0:
        raise DataError("no first-stage box matches a labelled vehicle: nothing to set the verifier's threshold on")
    k = int(np.floor((1.0 - keep_fraction) * len(pos) + 1e-9))
    return float(np.nextafter(pos[k], -np.inf))


def fit_verifier(c: Candidates, recipe: VerifierRecipe = VerifierRecipe(),
                 metadata: dict[str, Any] | None = None) -> tuple[BoxVerifier, dict[str, Any]]:
    """The verifier of ``c`` (module docstring) and a report: counts, the held-out operating
    point and what it keeps there (positives kept, negatives passed)."""
    rng = np.random.default_rng(recipe.seed)
    x = c.x if recipe.score_input else c.x[:, :-1]
    cams = np.unique(c.camera)
    if len(cams) < recipe.folds:
        raise DataError(f"{len(cams)} cameras: the verifier's operating point needs at least {recipe.folds} "
                        f"(one group of held-out cameras a fold)")
    sel = _thinned(c, recipe, rng)
    if not ((c.y[sel] == 1).any() and (c.y[sel] == 0).any()):
        raise DataError("the first stage's boxes hold no positives or no negatives: cannot fit a verifier")
    held = np.full(len(c), np.nan)
    for group in np.array_split(rng.permutation(cams), recipe.folds):
        out = np.isin(c.camera, group)
        tr = sel[~out[sel]]
        if not ((c.y[tr] == 1).any() and (c.y[tr] == 0).any()):
            raise DataError(f"cameras {', '.join(map(str, group))} hold every positive or every negative")
        coef, b, mean, scale = _fit(x[tr], c.y[tr], recipe.C)
        held[out] = ((x[out] - mean) / scale) @ coef + b
    labelled = c.y >= 0
    threshold = operating_point(held[labelled], c.y[labelled], recipe.keep_fraction)
    coef, b, mean, scale = _fit(x[sel], c.y[sel], recipe.C)
    pos, neg = c.y == 1, c.y == 0
    report = {"boxes": int(len(c)), "positives": int(pos.sum()), "negatives": int(neg.sum()),
              "fitted_rows": int(len(sel)), "cameras": int(len(cams)), "recipe": asdict(recipe),
              "threshold": threshold,
              "held_out_positives_kept": float((held[pos] > threshold).mean()) if pos.any() else None,
              "held_out_negatives_passed": float((held[neg] > threshold).mean()) if neg.any() else None}
    meta = {**(metadata or {}), "training": report}
    return BoxVerifier(VERIFIER_FEATURES, VERIFIER_CONTEXTS, recipe.score_input, coef, b, mean, scale,
                       threshold, meta), report

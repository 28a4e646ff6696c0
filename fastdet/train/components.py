"""Training a detector component: a linear model of one aspect of vehicle box, learnt from
crops cut from annotated video frames (:mod:`fastdet.train.keyframes`).

A component (:class:`fastdet.Detector` ``components=``) covers the vehicles whose boxes
have a width / height in its :attr:`ComponentRecipe.aspect` range, as the components of a
deformable-parts model cover views of an object by aspect ratio (Felzenszwalb et al., PAMI
2010): the rear-view main model keeps the near-square boxes, a *side* component the wide
ones (parked cars seen from the side, cars crossing). Its training set:

- positives: the annotated targets of that aspect, each cut at the component's window
  aspect (:func:`~fastdet.train.keyframes.window_around`) plus jittered copies, all also
  mirrored left-right;
- negatives: random windows of the annotated frames touching no annotated box, row bands
  of the data set's non-vehicle crops, and ``hard_rounds`` rounds of hard negatives: the
  windows a model of the round before fires on in the annotated frames, touching no box.

Only annotated frames are used (a keyframe clip's other frames have no labels). Which clips
a model learns from is the caller's choice: a clip it saw must not score it (leave one clip
out, ``tools/studies/components_loo.py``).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..config import FeatureConfig, SearchConfig
from ..detections import FIRST_COMPONENT_PART
from ..features import extract_features
from ..model import Model
from .dataset import load_folder
from .fit import fit_classifier
from .keyframes import AnnotatedFrame, background_crops, false_window_crops, positive_crops


@dataclass(frozen=True)
class ComponentRecipe:
    """How a component is trained.

    name: what it is called (recorded in the model's metadata).
    features: its window and features (:class:`~fastdet.config.FeatureConfig`; width 64 and
        8-px cells as the main model, so the guided search plans its bands the same way).
    aspect: ``[lo, hi)`` width / height of the annotated boxes that are its positives.
    min_width: smallest positive, a fraction of the frame width.
    margin: context around a positive, a fraction of its window on each side.
    jitter: moved and rescaled copies per positive (``shift``, ``zoom`` of
        :func:`~fastdet.train.keyframes.positive_crops`).
    background: random background windows per annotated frame.
    data_negatives: row bands of the data set's non-vehicle crops (a seeded random choice).
    hard_rounds: rounds of hard-negative mining; hard_per_frame: at most this many per frame
        and round.
    C: inverse regularisation of the logistic regression (the main model's classifier, so
        the scores are of the same kind).
    seed: every random choice.
    """

    name: str
    features: FeatureConfig
    aspect: tuple[float, float]
    min_width: float = 0.03
    margin: float = 0.0625
    jitter: int = 8
    background: int = 40
    data_negatives: int = 6000
    hard_rounds: int = 1
    hard_per_frame: int = 40
    C: float = 0.01
    seed: int = 0

    def __post_init__(self) -> None:
        lo, hi = self.aspect
        if not 0 <= lo < hi:
            raise ValueError(f"aspect must be [lo, hi) with 0 <= lo < hi, got {self.aspect!r}")
        if min(self.jitter, self.background, self.data_negatives, self.hard_rounds, self.hard_per_frame) < 0:
            raise ValueError("jitter, background, data_negatives, hard_rounds and hard_per_frame must be >= 0")
        if not self.C > 0:
            raise ValueError(f"C must be > 0, got {self.C!r}")

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["features"] = self.features.to_dict()
        d["aspect"] = [float(self.aspect[0]), None if np.isinf(self.aspect[1]) else float(self.aspect[1])]
        return d


#: the side-view component: boxes at least 1.6 times as wide as tall (parked cars seen from
#: the side, cars at an angle, the Udacity clips' cars in the next lane) in 64x32 windows
SIDE_RECIPE = ComponentRecipe("side", FeatureConfig(window=64, window_height=32, orientations=9), (1.6, float("inf")))


@dataclass
class ComponentData:
    """Counts of what a component was trained on (recorded in its metadata)."""

    positives: int = 0
    background: int = 0
    data_negatives: int = 0
    hard_negatives: list[int] = field(default_factory=list)


def data_negative_bands(data: Path, config: FeatureConfig, n: int, seed: int) -> np.ndarray:
    """``(n, win_h, win_w, 3) uint8``: rows ``[o, o + win_h)`` (random ``o``) of ``n`` random
    non-vehicle crops of the data set (each resized to the window width first if need be)."""
    neg = load_folder(Path(data) / "non-vehicles", 0, Path(data), size=config.win_w).images
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(neg), min(n, len(neg)), replace=False)
    offs = rng.integers(0, neg.shape[1] - config.win_h + 1, len(idx))
    if not len(idx):
        return np.zeros((0, config.win_h, config.win_w, 3), np.uint8)
    return np.stack([neg[i, o: o + config.win_h] for i, o in zip(idx, offs)])


def _features(images: np.ndarray, config: FeatureConfig) -> np.ndarray:
    return extract_features(images, config) if len(images) else np.zeros((0, config.n_features))


def train_component(recipe: ComponentRecipe, frames: Sequence[AnnotatedFrame], data: Path,
                    search: SearchConfig, main_model: Model | None = None,
                    log: Callable[[str], None] = print) -> Model:
    """A component model trained on ``frames`` (and the data set's non-vehicles under
    ``data``) as the module docstring says. ``search``: where the component searches, for
    mining hard negatives (beside ``main_model``, default the bundled one, whose windows are
    not mined). ``ValueError`` when the frames hold no positive of the recipe's aspect."""
    from ..detect import Detector

    t0 = time.perf_counter()
    cfg = recipe.features
    counts = ComponentData()
    pos = positive_crops(frames, cfg.win_w, cfg.win_h, recipe.aspect, recipe.min_width, recipe.margin,
                         recipe.jitter, seed=recipe.seed)
    if not len(pos):
        raise ValueError(f"component {recipe.name!r}: no annotated box with width/height in {recipe.aspect}")
    pos = np.concatenate([pos, pos[:, :, ::-1]])
    bg = background_crops(frames, cfg.win_w, cfg.win_h, recipe.background, seed=recipe.seed)
    dn = data_negative_bands(data, cfg, recipe.data_negatives, recipe.seed)
    counts.positives, counts.background, counts.data_negatives = len(pos), len(bg), len(dn)
    xs = [_features(pos, cfg), _features(bg, cfg), _features(dn, cfg)]
    log(f"{recipe.name}: {len(pos)} positives (with mirrored copies), {len(bg)} background, "
        f"{len(dn)} data-set negatives ({time.perf_counter() - t0:.1f} s)")
    clips = sorted({f.clip for f in frames})
    model = None
    for r in range(recipe.hard_rounds + 1):
        x = np.concatenate(xs)
        y = np.r_[np.ones(len(pos)), np.zeros(len(x) - len(pos))]
        scaler, clf = fit_classifier(x, y, "logreg", recipe.C, recipe.seed)
        model = Model(cfg, clf.coef_.ravel(), float(clf.intercept_[0]), scaler.mean_, scaler.scale_, "logreg",
                      metadata={"component": {"recipe": recipe.to_dict(), "clips": clips,
                                              "frames": len(frames), "data": asdict(counts)}})
        if r == recipe.hard_rounds:
            break
        det = Detector(main_model, components=[(model, search)])
        wins = []
        for f in frames:
            d = det.detect(f.image)
            wins.append(d.boxes[d.part == FIRST_COMPONENT_PART])
        hard = false_window_crops(frames, wins, cfg.win_w, cfg.win_h, recipe.hard_per_frame, seed=recipe.seed + r)
        counts.hard_negatives.append(len(hard))
        xs.append(_features(hard, cfg))
        log(f"{recipe.name}: round {r + 1}: {sum(len(w) for w in wins)} windows fire, {len(hard)} touch no "
            f"annotated box ({time.perf_counter() - t0:.1f} s)")
    assert model is not None
    log(f"{recipe.name}: trained on {len(frames)} frames of {', '.join(clips)} ({time.perf_counter() - t0:.1f} s)")
    return model

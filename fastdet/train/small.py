"""Training the small-vehicle component: a linear model of the data set's crops shrunk to its
window (:data:`~fastdet.config.SMALL_FEATURES`, 32x32), for vehicles too small for the main
model (Park, Ramanan & Fowlkes, "Multiresolution models for object detection", ECCV 2010: a
coarse template for small instances, trained on downscaled examples).

Its training set comes from the data set's crops only (``vehicles/``, ``non-vehicles/``), never
from a frame of an annotated clip, so no clip needs to be held out to score it:

- positives: every vehicle crop shrunk to the window (``cv2.INTER_AREA``), and mirrored;
- negatives: every non-vehicle crop shrunk the same way (and mirrored), plus window-sized tiles
  cut at the crops' own resolution: ``tiles`` random tiles of each non-vehicle crop (road,
  verge and trees at the fine scale the frame shows them, where the shrunk crops only show
  them coarse) and ``part_tiles`` random tiles of each vehicle crop (a quarter of a car: in the
  frame, the small windows lie on the parts of every near vehicle).

The classifier, the splits and the report are those of :func:`fastdet.train.fit.train`.

Optionally (``frames``, annotated frames of clips: :mod:`fastdet.train.keyframes`) one round
of hard negatives: the windows the data-set model fires on in those frames that touch no
annotated box (at most ``hard_per_frame`` a frame). A model that learnt from a clip's frames
must not score that clip: leave one clip out (``tools/studies/small_model.py --loo``).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..config import FeatureConfig, SearchBand, SearchConfig
from ..config.small import SMALL_FEATURES, SMALL_SCALES
from ..model import Model
from .dataset import CropSet, load_folder
from .fit import train
from .keyframes import AnnotatedFrame, false_window_crops

#: the logistic regression's inverse regularisation (the main model's)
SMALL_C = 0.0218


@dataclass(frozen=True)
class SmallRecipe:
    """How the small-vehicle component is trained (module docstring).

    features: its window and features (square, ``window`` px).
    tiles: native-resolution tiles per non-vehicle crop (negatives).
    part_tiles: native-resolution tiles per vehicle crop (negatives: parts of a vehicle).
    C: inverse regularisation of the logistic regression.
    hard_per_frame: hard negatives kept per annotated frame (when frames are given).
    split: held-out check reported in the metadata (:func:`fastdet.train.fit.train`).
    seed: every random choice.
    """

    features: FeatureConfig = field(default_factory=lambda: SMALL_FEATURES)
    tiles: int = 2
    part_tiles: int = 1
    C: float = SMALL_C
    hard_per_frame: int = 40
    split: str = "sequence"
    seed: int = 0

    def __post_init__(self) -> None:
        if self.features.window_height is not None:
            raise ValueError("the small component's windows are square")
        if self.features.win_w > 64:
            raise ValueError(f"the window ({self.features.win_w} px) must not exceed the data set's 64-px crops")
        if self.tiles < 0 or self.part_tiles < 0 or self.hard_per_frame < 0:
            raise ValueError("tiles, part_tiles and hard_per_frame must be >= 0")
        if not self.C > 0:
            raise ValueError(f"C must be > 0, got {self.C!r}")

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["features"] = self.features.to_dict()
        return d


def random_tiles(images: np.ndarray, side: int, per_image: int, seed: int) -> np.ndarray:
    """``(len(images) * per_image, side, side, 3)``: ``per_image`` tiles of each image at random
    places (a seeded choice), at the image's own resolution."""
    n, h, w = images.shape[:3]
    if side > min(h, w):
        raise ValueError(f"tiles of {side} px do not fit {w}x{h} images")
    if per_image == 0 or n == 0:
        return np.zeros((0, side, side, 3), np.uint8)
    rng = np.random.default_rng(seed)
    ys = rng.integers(0, h - side + 1, (n, per_image))
    xs = rng.integers(0, w - side + 1, (n, per_image))
    return np.stack([images[i, y: y + side, x: x + side] for i in range(n)
                     for y, x in zip(ys[i], xs[i])])


def tile_negatives(data: Path, recipe: SmallRecipe) -> CropSet | None:
    """The native-resolution negatives of ``recipe`` (``tiles`` of the non-vehicles, ``part_tiles``
    of the vehicles), labelled 0; ``None`` when it asks for none."""
    parts = []
    side = recipe.features.win_w
    for folder, k, seed in (("non-vehicles", recipe.tiles, recipe.seed), ("vehicles", recipe.part_tiles,
                                                                          recipe.seed + 1)):
        if k:
            crops = load_folder(Path(data) / folder, 0, Path(data), size=64)
            parts.append(random_tiles(crops.images, side, k, seed))
    if not parts:
        return None
    images = np.concatenate(parts)
    n = len(images)
    return CropSet(images, np.zeros(n, np.int64), np.full(n, "tiles"), np.arange(n, dtype=np.int64))


def mining_search(rows: tuple[int, int] = (216, 576)) -> SearchConfig:
    """Where hard negatives are mined: the small search's window sizes over rows ``rows`` of a
    1280x720 frame (0.3-0.8 of the height, rescaled to the frame; wherever the horizon of a
    clip's camera puts the small search, it lies in there)."""
    return SearchConfig(bands=tuple(SearchBand(s, *rows) for s in SMALL_SCALES), cells_per_step=1, threshold=0.0,
                        shrink="area")


def hard_negatives(model: Model, frames: Sequence[AnnotatedFrame], per_frame: int, seed: int = 0) -> CropSet:
    """The windows ``model`` fires on in ``frames`` (:func:`mining_search`) that touch no
    annotated box, cut to its window (``INTER_AREA``), at most ``per_frame`` a frame, labelled 0."""
    from ..detect import Detector

    det = Detector(model, search=mining_search())
    wins = [det.detect(f.image).boxes for f in frames]
    cfg = model.config
    images = false_window_crops(frames, wins, cfg.win_w, cfg.win_h, per_frame, seed=seed)
    n = len(images)
    return CropSet(images, np.zeros(n, np.int64), np.full(n, "hard"), np.arange(n, dtype=np.int64))


def train_small(data: Path, recipe: SmallRecipe = SmallRecipe(), command: str | None = None,
                frames: Sequence[AnnotatedFrame] = (), base: Model | None = None, log=print) -> Model:
    """The small-vehicle component trained on the data set under ``data`` as ``recipe`` says;
    ``command``: how it was made (recorded in its metadata with the recipe and the report).
    ``frames``: annotated frames to mine one round of hard negatives in, with ``base`` (default:
    the data-set model of the same recipe, trained first)."""
    extra = tile_negatives(data, recipe)
    clips: list[str] = sorted({f.clip for f in frames})
    n_hard = 0
    if frames and recipe.hard_per_frame:
        if base is None:
            base = train_small(data, recipe, command, log=log)
        hard = hard_negatives(base, frames, recipe.hard_per_frame, recipe.seed)
        n_hard = len(hard)
        log(f"small: {n_hard} hard negatives from {len(frames)} frames of {', '.join(clips)}")
        if n_hard:
            extra = hard if extra is None else CropSet.concat(extra, hard)
    model, report = train(Path(data), recipe.features, "logreg", recipe.C, split=recipe.split, seed=recipe.seed,
                          extra_crops=extra, crop_size=recipe.features.win_w, progress=False, log=log)
    assert model is not None
    meta = dict(model.metadata)
    meta["small"] = {"recipe": recipe.to_dict(), "command": command, "hard_negative_clips": clips,
                     "hard_negatives": n_hard}
    return Model(model.config, model.coef, model.intercept, model.mean, model.scale, model.classifier, metadata=meta)

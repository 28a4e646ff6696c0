"""Training crops from labelled pictures of many cameras (:mod:`fastdet.labels`): positives cut
around every target box, negatives from the background of pictures whose labels are complete,
and hard negatives -- the windows a model fires on there that touch no labelled box.

A picture whose labels are partial (``complete=False``: only some vehicles boxed, some kinds
never) gives positives only: a crop of its background may hold an unlabelled vehicle. Every
crop is tagged with its picture's camera (``CropSet.groups``), so a split by camera keeps one
camera's crops on one side.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np

from ..config import FeatureConfig
from ..labels.load import load_pictures
from ..labels.picture import AnnotatedPicture
from ..model import Model
from .dataset import CropSet
from .keyframes import AnnotatedFrame, background_crops, positive_crops
from .windows import FrameWindows, score_frames


def as_frame(pic: AnnotatedPicture, image: np.ndarray) -> AnnotatedFrame:
    """``pic`` with its pixels as the keyframe code's :class:`AnnotatedFrame`."""
    return AnnotatedFrame(pic.camera, pic.frame or 0, image, pic.targets, pic.ignores)


def _crop_set(images: list[np.ndarray], label: int, groups: list[str], win_h: int, win_w: int) -> CropSet:
    imgs = np.concatenate(images) if images else np.zeros((0, win_h, win_w, 3), np.uint8)
    n = len(imgs)
    return CropSet(imgs, np.full(n, label, np.int64), np.array(groups, dtype=object).reshape(n),
                   np.arange(n, dtype=np.int64))


def picture_crops(pictures: Sequence[AnnotatedPicture], config: FeatureConfig, jitter: int = 1,
                  negatives_per_picture: int = 8, seed: int = 0,
                  frames: Iterable[tuple[AnnotatedPicture, np.ndarray]] | None = None,
                  tick: Callable[[], None] | None = None) -> CropSet:
    """Labelled crops of the model's window size, ``(N, win_h, win_w, 3) uint8``: one crop per
    target box of every picture plus ``jitter`` shifted / rescaled copies
    (:func:`~fastdet.train.keyframes.positive_crops`), and ``negatives_per_picture`` random
    background windows (1/20 to 2/5 of the picture's width) touching no labelled box, from
    complete pictures only. ``frames``: the pictures with their pixels, when already decoded
    (default: decoded here, a video once for all its frames)."""
    pos, neg, gpos, gneg = [], [], [], []
    rng = np.random.default_rng(seed)
    for pic, image in (frames if frames is not None else load_pictures(pictures)):
        f = as_frame(pic, image)
        s = int(rng.integers(2**31))
        p = positive_crops([f], config.win_w, config.win_h, jitter=jitter, seed=s)
        pos.append(p)
        gpos += [pic.camera] * len(p)
        if pic.complete and negatives_per_picture:
            n = background_crops([f], config.win_w, config.win_h, negatives_per_picture, seed=s)
            neg.append(n)
            gneg += [pic.camera] * len(n)
        if tick is not None:
            tick()
    return CropSet.concat(_crop_set(pos, 1, gpos, config.win_h, config.win_w),
                          _crop_set(neg, 0, gneg, config.win_h, config.win_w))


def hard_negative_crops(model: Model, pictures: Sequence[AnnotatedPicture], per_picture: int = 20,
                        min_score: float = 0.0, seed: int = 0,
                        frames: Iterable[tuple[AnnotatedPicture, np.ndarray]] | None = None,
                        tick: Callable[[], None] | None = None, **search) -> CropSet:
    """Hard negatives: on every complete picture, the windows of a dense search over the whole
    picture (:func:`~fastdet.train.windows.dense_search`; ``search``: its keyword arguments)
    that ``model`` scores above ``min_score`` and that touch no labelled box (target or ignore
    region), cut and resized to the window; the ``per_picture`` highest-scoring of them.
    Partial pictures are skipped."""
    from .keyframes import window_crops

    crops: list[np.ndarray] = []
    groups: list[str] = []
    win_w, win_h = model.config.win_w, model.config.win_h

    def keep(f: AnnotatedFrame, fw: FrameWindows) -> None:
        sel = np.flatnonzero(fw.false > min_score)
        sel = sel[np.argsort(-fw.false[sel])][:per_picture]
        c = window_crops([f], [fw.false_boxes[sel]], win_w, win_h)
        crops.append(c)
        groups.extend([f.clip] * len(c))

    for pic, image in (frames if frames is not None else load_pictures(pictures)):
        if not pic.complete:
            continue
        if min(image.shape[:2]) < win_h:
            continue
        score_frames(model, [as_frame(pic, image)], on_frame=keep, **search)
        if tick is not None:
            tick()
    return _crop_set(crops, 0, groups, win_h, win_w)

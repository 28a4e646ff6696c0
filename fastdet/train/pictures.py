"""Training crops from labelled pictures of many cameras (:mod:`fastdet.labels`): positives cut
around every target box, negatives from the background of pictures whose labels are complete,
and hard negatives -- the windows a model fires on there that touch no labelled box.

A picture whose labels are partial (``complete=False``: only some vehicles boxed, some kinds
never) gives positives only: a crop of its background may hold an unlabelled vehicle. Every
crop is tagged with its picture's camera (``CropSet.groups``), so a split by camera keeps one
camera's crops on one side.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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


def crop_set(images: list[np.ndarray], label: int, groups: list[str], win_h: int, win_w: int) -> CropSet:
    """One :class:`CropSet` of ``images`` (arrays ``(k, win_h, win_w, 3) uint8`` to join, maybe
    none), every crop of ``label``, tagged with ``groups`` (one a crop), in that order."""
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
    return CropSet.concat(crop_set(pos, 1, gpos, config.win_h, config.win_w),
                          crop_set(neg, 0, gneg, config.win_h, config.win_w))


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
    return crop_set(crops, 0, groups, win_h, win_w)


@dataclass(frozen=True)
class PictureRecipe:
    """How a main model learns from labelled pictures besides the crop folders.

    every_other: keep one picture in ``every_other`` of each video's labelled frames (its
        neighbours are near copies); stills are all kept.
    aspect_range, min_box_width: the target boxes that become positives of a square window:
        width / height in ``[lo, hi)`` and at least this many pixels wide (a smaller box is a
        blur when scaled up to 64 px; a side view or a bus is not this window's shape); the
        other targets become ignore regions (no background crop is cut on them).
    rounds: rounds of hard negatives: the first mined with the bundled model, each next one
        with the model the previous round trained; every round's negatives are kept.
    jitter: shifted / rescaled copies of every positive crop.
    negatives_per_picture: random background windows of every complete picture.
    hard_per_picture: the highest-scoring false windows of the bundled model on every complete
        picture (dense search, ``mine_cells_per_step`` cells a step, ``mine_steps`` sizes an octave,
        windows scoring above ``mine_min_score``).
    C, truncate, truncate_keep, reencode: the logistic regression and the crop augmentation, as
        :func:`fastdet.train.fit.train` takes them (the bundled model's values).
    """

    every_other: int = 2
    aspect_range: tuple[float, float] = (0.7, 1.6)
    min_box_width: float = 40.0
    rounds: int = 2
    jitter: int = 1
    negatives_per_picture: int = 8
    hard_per_picture: int = 10
    mine_cells_per_step: int = 2
    mine_steps: int = 2
    mine_min_score: float = 0.0
    C: float = 0.0218
    truncate: float = 0.25
    truncate_keep: tuple[float, float] = (0.75, 0.875)
    reencode: float = 0.25

    def __post_init__(self) -> None:
        if self.every_other < 1 or self.jitter < 0 or self.negatives_per_picture < 0 or self.hard_per_picture < 0:
            raise ValueError("every_other >= 1; jitter, negatives_per_picture, hard_per_picture >= 0")
        if self.mine_cells_per_step < 1 or self.mine_steps < 1 or not self.C > 0 or self.rounds < 1:
            raise ValueError("mine_cells_per_step, mine_steps and rounds must be >= 1, C > 0")
        lo, hi = self.aspect_range
        if not 0 <= lo < hi or self.min_box_width < 0:
            raise ValueError(f"aspect_range must be 0 <= lo < hi and min_box_width >= 0, got {self.aspect_range}, "
                             f"{self.min_box_width}")

    def window_targets(self, pic: AnnotatedPicture) -> AnnotatedPicture:
        """``pic`` with only the targets of this window's kind (``aspect_range``,
        ``min_box_width``); the others moved to its ignore regions."""
        t = pic.targets
        w, h = t[:, 2] - t[:, 0], np.maximum(t[:, 3] - t[:, 1], 1e-9)
        ok = (w / h >= self.aspect_range[0]) & (w / h < self.aspect_range[1]) & (w >= self.min_box_width)
        if ok.all():
            return pic
        return dataclasses.replace(pic, targets=t[ok], ignores=np.concatenate([pic.ignores, t[~ok]]))


def thin_video_frames(pictures: Sequence[AnnotatedPicture], every_other: int) -> list[AnnotatedPicture]:
    """``pictures`` with only every ``every_other``-th labelled frame of each video kept (in
    their order; stills all kept)."""
    seen: dict[str, int] = {}
    out = []
    for p in pictures:
        if p.frame is None:
            out.append(p)
            continue
        k = seen.get(str(p.path), 0)
        seen[str(p.path)] = k + 1
        if k % every_other == 0:
            out.append(p)
    return out


def picture_training_crops(pictures: Sequence[AnnotatedPicture], config: FeatureConfig,
                           recipe: PictureRecipe = PictureRecipe(), base: Model | None = None,
                           progress: bool = True, log: Callable[[str], None] = print,
                           positives: bool = True) -> CropSet | None:
    """Every crop :func:`train_on_pictures` adds to the crop folders, as one labelled
    :class:`CropSet` of ``config``'s window (``None`` when there are none): positives and
    background of :func:`picture_crops`, and, when ``base`` (a model of the same features) is
    given, its hard negatives (:func:`hard_negative_crops`; only those with ``positives``
    false). Targets not of the window's kind are ignore regions (:meth:`PictureRecipe.window_targets`).
    Pictures are decoded one video at a time and dropped once cut."""
    from tqdm import tqdm

    if base is not None and base.config != config:
        raise ValueError("picture_training_crops: the mining model's features differ from the config's")
    pics = thin_video_frames(pictures, recipe.every_other)
    t0 = time.perf_counter()
    bar = tqdm(total=len(pics), desc="pictures", unit="picture", disable=not progress, leave=False)
    parts, n_hard = [], 0
    for pic, image in load_pictures(pics):
        pic = recipe.window_targets(pic)
        one = [(pic, image)]
        if positives:
            parts.append(picture_crops([pic], config, recipe.jitter, recipe.negatives_per_picture,
                                       seed=len(parts), frames=one))
        if base is not None and recipe.hard_per_picture and pic.complete:
            h = hard_negative_crops(base, [pic], recipe.hard_per_picture, recipe.mine_min_score, frames=one,
                                    cells_per_step=recipe.mine_cells_per_step, steps=recipe.mine_steps,
                                    threshold=recipe.mine_min_score)
            parts.append(h)
            n_hard += len(h)
        bar.update(1)
    bar.close()
    if not parts:
        return None
    extra = parts[0]
    for part in parts[1:]:
        extra = CropSet.concat(extra, part)
    log(f"pictures: {len(pics)} of {len(pictures)} ({len({p.camera for p in pics})} cameras): "
        f"{int(extra.labels.sum())} vehicle crops, {int((extra.labels == 0).sum()) - n_hard} background, "
        f"{n_hard} hard negatives ({time.perf_counter() - t0:.0f} s)")
    return extra


def _joined(parts: Sequence[CropSet | None]) -> CropSet | None:
    out = None
    for p in parts:
        if p is not None and len(p):
            out = p if out is None else CropSet.concat(out, p)
    return out


def train_on_pictures(data: Path, pictures: Sequence[AnnotatedPicture], recipe: PictureRecipe = PictureRecipe(),
                      base: Model | None = None, progress: bool = True, log: Callable[[str], None] = print,
                      max_per_folder: int | None = None) -> tuple[Model, dict[str, Any]]:
    """A main-window model from the crop folders of ``data`` plus crops of ``pictures``:
    positives and background (:func:`picture_training_crops`), then ``recipe.rounds`` rounds of
    hard negatives -- the first of ``base`` (default the bundled model, whose features it keeps),
    each next of the model the round before trained -- each round retrained on everything so
    far: ``(model, report)``. ``max_per_folder``: at most that many crops of each crop folder
    (quick runs)."""
    from ..model import load_model
    from .fit import train

    miner = load_model() if base is None else base
    config = miner.config
    crops = picture_training_crops(pictures, config, recipe, None, progress, log)
    hard: list[CropSet | None] = []
    rounds = []
    model, report = miner, {}
    for r in range(recipe.rounds):
        t0 = time.perf_counter()
        hard.append(picture_training_crops(pictures, config, recipe, miner, progress, log, positives=False))
        model, report = train(data, config, C=recipe.C, split="none", seed=0, extra_crops=_joined([crops, *hard]),
                              truncate=recipe.truncate, truncate_keep=recipe.truncate_keep, reencode=recipe.reencode,
                              progress=progress, log=log, max_per_folder=max_per_folder)
        rounds.append({"hard_negatives": 0 if hard[-1] is None else len(hard[-1]),
                       "seconds": round(time.perf_counter() - t0, 1)})
        log(f"round {r + 1} of {recipe.rounds}: {rounds[-1]['hard_negatives']} hard negatives "
            f"({rounds[-1]['seconds']:.0f} s)")
        miner = model
    pics = thin_video_frames(pictures, recipe.every_other)
    report["pictures"] = {"recipe": dataclasses.asdict(recipe), "pictures": len(pics),
                          "cameras": sorted({p.camera for p in pics}), "rounds": rounds}
    return model, report

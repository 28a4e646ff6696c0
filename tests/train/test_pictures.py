"""fastdet/train/pictures.py: crops from labelled pictures (positives around every target,
background only from complete pictures, hard negatives touching no labelled box)."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.boxes import intersection
from fastdet.config import FeatureConfig
from fastdet.labels import AnnotatedPicture
from fastdet.labels.load import load_pictures
from fastdet.model import load_model
from fastdet.train.pictures import hard_negative_crops, picture_crops

CFG = FeatureConfig()


def _picture(tmp_path, name: str, targets, ignores=(), complete: bool = True, seed: int = 0) -> AnnotatedPicture:
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (240, 320, 3), dtype=np.uint8)
    for x1, y1, x2, y2 in targets:  # a flat grey car, so a crop of it is recognisable
        img[int(y1):int(y2), int(x1):int(x2)] = 128
    path = tmp_path / f"{name}.png"
    cv2.imwrite(str(path), img)
    return AnnotatedPicture("synthetic", f"cam/{name}", name, path, 320, 240, np.array(targets, float).reshape(-1, 4),
                            np.array(ignores, float).reshape(-1, 4), complete)


def test_positives_per_target_and_background_only_from_complete_pictures(tmp_path) -> None:
    full = _picture(tmp_path, "a", [(100, 80, 164, 144), (10, 10, 58, 58)])
    partial = _picture(tmp_path, "b", [(200, 100, 264, 164)], complete=False, seed=1)
    crops = picture_crops([full, partial], CFG, jitter=2, negatives_per_picture=5, seed=0)
    pos, neg = crops.labels == 1, crops.labels == 0
    assert pos.sum() == 3 * 3  # each target and 2 jittered copies
    assert neg.sum() == 5      # background from the complete picture only
    assert crops.images.shape[1:] == (64, 64, 3) and crops.images.dtype == np.uint8
    assert set(crops.groups[neg]) == {"cam/a"}
    assert list(crops.groups[pos]).count("cam/b") == 3
    # the un-jittered positive of the square target is the grey car itself (margin 1/16: a
    # grey middle, the random border around it)
    first = crops.images[pos][0].astype(float)
    assert np.abs(first[8:56, 8:56] - 128).max() < 1


def test_background_touches_no_labelled_box(tmp_path) -> None:
    pic = _picture(tmp_path, "c", [(100, 80, 164, 144)], ignores=[(200, 20, 260, 60)])
    frames = list(load_pictures([pic]))
    crops = picture_crops([pic], CFG, jitter=0, negatives_per_picture=30, seed=3, frames=frames)
    neg = crops.images[crops.labels == 0]
    assert len(neg) > 0
    # no background crop holds any of the flat grey car (INTER_AREA of noise is never 128 in
    # all three channels over a 2x2 patch; the car's pixels are)
    grey = np.all(neg == 128, axis=3)
    assert not (grey[:, :-1, :-1] & grey[:, 1:, :-1] & grey[:, :-1, 1:] & grey[:, 1:, 1:]).any()


@pytest.mark.slow
def test_hard_negatives_touch_no_box_and_skip_partial_pictures(tmp_path) -> None:
    model = load_model()
    pics = [_picture(tmp_path, "d", [(100, 80, 164, 144)], seed=4),
            _picture(tmp_path, "e", [], complete=False, seed=5)]
    boxes_seen: list[np.ndarray] = []
    from fastdet.train import windows

    real = windows.score_frames

    def spy(model, frames, on_frame=None, **search):
        def keep(f, fw):
            boxes_seen.append(fw.false_boxes)
            on_frame(f, fw)
        return real(model, frames, on_frame=keep, **search)

    import fastdet.train.pictures as mod
    mod.score_frames, old = spy, mod.score_frames
    try:
        hard = hard_negative_crops(model, pics, per_picture=7, min_score=-np.inf, cells_per_step=2, steps=1)
    finally:
        mod.score_frames = old
    assert len(boxes_seen) == 1  # the partial picture is never mined
    assert len(hard) == 7 and set(hard.labels) == {0} and set(hard.groups) == {"cam/d"}
    b = boxes_seen[0]
    assert not np.any(intersection(b, pics[0].boxes) > 0)


def test_thin_video_frames_keeps_every_nth_frame_of_each_video_and_every_still(tmp_path) -> None:
    from fastdet.train.pictures import thin_video_frames

    def pic(path, frame):
        return AnnotatedPicture("s", "c", f"{path}:{frame}", tmp_path / path, 64, 64, frame=frame)

    pics = [pic("a.mp4", f) for f in (1, 6, 11, 16, 21)] + [pic("s.jpg", None), pic("b.mp4", 3), pic("b.mp4", 8),
                                                             pic("t.jpg", None)]
    kept = thin_video_frames(pics, 2)
    # a plain loop: the k-th labelled frame of its video is kept when k is even; stills always
    seen: dict[str, int] = {}
    want = []
    for p in pics:
        k = seen.get(p.name.split(":")[0], 0)
        seen[p.name.split(":")[0]] = k + 1
        if p.frame is None or k % 2 == 0:
            want.append(p.name)
    assert [p.name for p in kept] == want == ["a.mp4:1", "a.mp4:11", "a.mp4:21", "s.jpg:None", "b.mp4:3", "t.jpg:None"]
    assert thin_video_frames(pics, 1) == pics


def test_picture_recipe_checks_its_numbers() -> None:
    from fastdet.train.pictures import PictureRecipe

    for bad in ({"every_other": 0}, {"jitter": -1}, {"C": 0.0}, {"mine_steps": 0}):
        with pytest.raises(ValueError):
            PictureRecipe(**bad)

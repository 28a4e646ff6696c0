"""The main model trained with crops of annotated frames: what is cut (positives, background, hard
negatives that touch no annotated box), that it joins the training set, and what is recorded."""
from __future__ import annotations

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

from fastdet.boxes import intersection, iou
from fastdet.config import FeatureConfig
from fastdet.model import load_model
from fastdet.train import fit
from fastdet.train.dataset import CropSet
from fastdet.train.keyframe_model import KeyframeRecipe, keyframe_crops, train_keyframe_model
from fastdet.train.keyframes import aspect_of, cut, read_annotated_frames
from fastdet.train.windows import score_frames


@pytest.fixture(scope="module")
def frames(data):
    return read_annotated_frames(data, "boston_street")[:3]


@pytest.fixture(scope="module")
def small_data(data, tmp_path_factory):
    """A data folder of 60 vehicle and 60 non-vehicle crops of the shared one (loads in no time)."""
    root = tmp_path_factory.mktemp("small_data")
    for sub in ("vehicles", "non-vehicles"):
        for folder in sorted(p for p in (data / sub).iterdir() if p.is_dir())[:2]:
            (root / sub / folder.name).mkdir(parents=True)
            for png in sorted(folder.glob("*.png"))[:30]:
                shutil.copy(png, root / sub / folder.name / png.name)
    return root


def test_keyframe_crops(frames):
    recipe = KeyframeRecipe(jitter=2, background=5, hard_per_frame=7)
    kc = keyframe_crops(frames, recipe)
    n_targets = sum(len(f.targets) for f in frames)
    assert kc.positives == 3 * n_targets and kc.background <= 15 and kc.hard <= 21
    c = kc.crops
    assert c.images.shape[1:] == (64, 64, 3) and len(c) == kc.positives + kc.background + kc.hard
    assert c.labels.tolist() == [1] * kc.positives + [0] * (kc.background + kc.hard)
    assert set(c.groups[: kc.positives]) == {"keyframes/boston_street"}
    # the hard negatives are the bundled model's false windows above 0.5 (at most 7 a frame)
    fired = []
    score_frames(load_model(None), frames, on_frame=lambda f, fw: fired.append(fw.false_boxes[fw.false > 0.5]),
                 cells_per_step=2)
    assert kc.fired == sum(len(w) for w in fired) > 0
    assert kc.hard == sum(min(len(w), 7) for w in fired)
    for f, w in zip(frames, fired):
        assert not (intersection(w, f.boxes) > 0).any()
    hard = c.images[kc.positives + kc.background:]
    all_cuts = [cut(f.image, b, 64, 64) for f, w in zip(frames, fired) for b in w]
    assert all(any(np.array_equal(h, a) for a in all_cuts) for h in hard)
    # seeded
    again = keyframe_crops(frames, recipe)
    np.testing.assert_array_equal(again.crops.images, c.images)
    with pytest.raises(ValueError):
        keyframe_crops(frames, recipe, config=FeatureConfig(window_height=32))
    with pytest.raises(ValueError):
        replace(recipe, hard_threshold=1.5)
    with pytest.raises(ValueError):
        replace(recipe, max_aspect=0)
    # only the targets narrower than max_aspect are positives
    narrow = keyframe_crops(frames, replace(recipe, max_aspect=1.3, hard_per_frame=0))
    assert narrow.positives == 3 * int(sum((aspect_of(f.targets) < 1.3).sum() for f in frames)) < kc.positives
    assert narrow.hard == 0 and json.loads(json.dumps(recipe.to_dict()))["max_aspect"] is None
    with pytest.raises(ValueError):
        replace(recipe, near_iou=0.7)
    with pytest.raises(ValueError):
        replace(recipe, near_per_frame=-1)


def test_near_misses_join_the_hard_negatives(frames):
    recipe = KeyframeRecipe(jitter=0, background=0, hard_per_frame=0, near_per_frame=5)
    kc = keyframe_crops(frames, recipe)
    near = []
    score_frames(load_model(None), frames, on_frame=lambda f, fw: near.append(fw.near_boxes[fw.near > 0.5]),
                 cells_per_step=2, near_iou=0.3)
    assert kc.hard == sum(min(len(w), 5) for w in near) > 0
    for f, w in zip(frames, near):  # each touches a target, none at IoU >= 0.3
        assert (intersection(w, f.targets) > 0).any(axis=1).all() and (iou(w, f.targets) < 0.3).all()
    hard = kc.crops.images[kc.positives:]
    all_cuts = [cut(f.image, b, 64, 64) for f, w in zip(frames, near) for b in w]
    assert all(any(np.array_equal(h, a) for a in all_cuts) for h in hard)


def test_train_keyframe_model_records_and_learns_its_positives(frames, small_data):
    recipe = KeyframeRecipe(jitter=1, background=5, hard_per_frame=10)
    logs: list[str] = []
    m = train_keyframe_model(small_data, FeatureConfig(), frames, recipe, log=logs.append, C=0.03)
    tr = m.metadata["training"]
    kf = tr["keyframes"]
    assert kf["clips"] == ["boston_street"] and kf["frames"] == 3 and kf["recipe"]["jitter"] == 1
    assert tr["data"]["extra_positives"] == kf["positives"] == 2 * sum(len(f.targets) for f in frames)
    assert tr["data"]["hard_negatives"] == kf["background"] + sum(kf["hard_negatives"])
    assert "random_split" not in tr and any("keyframes of boston_street" in s for s in logs)
    # a model trained on the same few data-set crops without them scores those targets lower
    kc = keyframe_crops(frames, replace(recipe, jitter=0))
    pos = kc.crops.images[: kc.positives]
    plain, _ = fit.train(small_data, FeatureConfig(), C=0.03, split="none", progress=False, log=lambda s: None)
    assert np.mean(m.decision_function(pos) > 0) > np.mean(plain.decision_function(pos) > 0)


def test_fit_rejects_a_bad_split_and_extra_crops_of_another_size(data):
    with pytest.raises(ValueError, match="split"):
        fit.train(data, FeatureConfig(), split="nope")
    odd = CropSet(np.zeros((2, 32, 64, 3), np.uint8), np.ones(2, np.int64), np.array(["x", "x"]), np.arange(2))
    with pytest.raises(ValueError, match="extra_crops"):
        fit.train(data, FeatureConfig(), split="none", progress=False, extra_crops=odd, log=lambda s: None)

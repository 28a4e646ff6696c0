"""fastdet.train.adapt: the footage's plan (sampling, the kept-aside stretch, mixed sizes), the
teacher's labels kept per clip and never recomputed, the split of the pictures, and the choice
of the operating point. The whole command: tests/cli/test_adapt.py."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fastdet.config.adapt import AdaptConfig
from fastdet.errors import DataError
from fastdet.labels.picture import AnnotatedPicture
from fastdet.teacher.yolox import TeacherBoxes
from fastdet.train import adapt
from tests.media import write_video


class CountingTeacher:
    """Boxes one car in the middle of every frame; counts its calls by frame size."""

    def __init__(self) -> None:
        self.calls = 0

    def detect(self, frame: np.ndarray) -> TeacherBoxes:
        self.calls += 1
        h, w = frame.shape[:2]
        return TeacherBoxes(np.array([[w * 0.4, h * 0.5, w * 0.6, h * 0.7]]), np.array([0.9], np.float32),
                            np.array([2], np.int16))


def test_config_checks_and_step():
    c = AdaptConfig(every=5, max_frames=100)
    assert c.step(300) == 5 and c.step(1000) == 10 and c.step(1001) == 11
    assert AdaptConfig(offsets=(1, 0, 1)).offsets == (0.0, 1.0)
    for bad in ({"every": 0}, {"holdout": 1.0}, {"holdout": 0}, {"weight": 0}, {"offsets": ()},
                {"offsets": (math.nan,)}, {"truncate_keep": (0.9, 0.8)}, {"max_frames": 1}, {"holdout_every": 0}):
        with pytest.raises(ValueError):
            AdaptConfig(**bad)  # type: ignore[arg-type]
    assert AdaptConfig.from_dict(c.to_dict()) == c


def test_plan_samples_evenly_and_keeps_the_end_of_each_video_aside(tmp_path):
    a = write_video(tmp_path / "a.mp4", 50)
    b = write_video(tmp_path / "b.mp4", 30)
    fp = adapt.plan_footage([str(a), str(b)], AdaptConfig(every=2, max_frames=20, holdout=0.2, holdout_every=2))
    assert fp.step == 4 and fp.size == (320, 240)  # 80 frames / 20
    ca, cb = fp.clips
    assert (ca.frames, ca.holdout_start, cb.frames, cb.holdout_start) == (50, 41, 30, 25)
    assert ca.train_frames(fp.step) == list(range(1, 41, 4))
    assert ca.holdout_frames(fp.holdout_every) == [41, 43, 45, 47, 49]  # a contiguous stretch, labelled every 2nd
    assert fp.holdout_length == 10 + 6 and fp.n_train == 10 + 6 and fp.n_holdout == 5 + 3
    # by default every kept-aside frame is labelled, whatever the sampling step
    every = adapt.plan_footage([str(a), str(b)], AdaptConfig(every=2, max_frames=20, holdout=0.2))
    assert every.clips[0].holdout_frames(every.holdout_every) == list(range(41, 51)) and every.n_holdout == 10 + 6
    assert every.n_train == fp.n_train


def test_plan_refuses_mixed_sizes_and_clashing_names(tmp_path):
    a = write_video(tmp_path / "a.mp4", 10)
    b = write_video(tmp_path / "b.mp4", 10, w=160, h=120)
    with pytest.raises(DataError, match=r"160x120, .*a.mp4's are 320x240"):
        adapt.plan_footage([str(a), str(b)], AdaptConfig())
    (tmp_path / "x").mkdir()
    a2 = write_video(tmp_path / "x" / "a.mp4", 10)
    with pytest.raises(DataError, match="two videos named 'a'"):
        adapt.plan_footage([str(a), str(a2)], AdaptConfig())
    with pytest.raises(DataError, match="no video"):
        adapt.plan_footage([], AdaptConfig())


def test_labels_are_kept_per_clip_and_not_recomputed(tmp_path):
    a = write_video(tmp_path / "a.mp4", 20)
    b = write_video(tmp_path / "b.mp4", 20)
    fp = adapt.plan_footage([str(a), str(b)], AdaptConfig(every=5, holdout=0.25, holdout_every=5))
    work = tmp_path / "work"
    teacher = CountingTeacher()
    labels, now = adapt.label_clips(fp, teacher, work, progress=False, log=lambda s: None)  # type: ignore[arg-type]
    planned = [fp.planned(c) for c in fp.clips]
    assert planned[0] == [1, 6, 11, 16] and teacher.calls == now == 8
    again = CountingTeacher()
    labels2, now2 = adapt.label_clips(fp, again, work, progress=False, log=lambda s: None)  # type: ignore[arg-type]
    assert again.calls == now2 == 0 and labels2 == labels
    # the pictures: targets from the teacher, split at each clip's kept-aside stretch
    pics = adapt.teacher_pictures(fp, labels, 0.3)
    train, held = adapt.split_pictures(fp, pics)
    assert [p.frame for p in train] == [1, 6, 11, 1, 6, 11] and all(len(p.targets) == 1 for p in pics)
    assert {k: [p.frame for p in v] for k, v in held.items()} == {"a": [16], "b": [16]}
    # another plan (other frames) is labelled anew (it replaces the clip's labels)
    fp2 = adapt.plan_footage([str(a), str(b)], AdaptConfig(every=4, holdout=0.25, holdout_every=4))
    third = CountingTeacher()
    adapt.label_clips(fp2, third, work, progress=False, log=lambda s: None)  # type: ignore[arg-type]
    assert third.calls == sum(len(fp2.planned(c)) for c in fp2.clips)


def test_a_still_picture_always_trains(tmp_path):
    a = write_video(tmp_path / "a.mp4", 20)
    fp = adapt.plan_footage([str(a)], AdaptConfig(every=5))
    still = AnnotatedPicture("s", "c", "x.jpg", tmp_path / "x.jpg", 320, 240)
    late = AnnotatedPicture("s", "c", "a:20", a, 320, 240, frame=20)
    train, held = adapt.split_pictures(fp, [still, late])
    assert train == [still] and held == {"a": [late]}


def test_clip_key_changes_with_the_video(tmp_path: Path):
    a = write_video(tmp_path / "a.mp4", 5)
    clip = adapt.Clip(str(a), "a", 5, 5)
    k = clip.key
    write_video(tmp_path / "a.mp4", 6)
    assert clip.key != k and k.startswith("a-")


def test_a_sample_weight_counts_as_that_many_copies_of_the_row():
    """fit_classifier with weight 3 on some rows fits the model of those rows repeated 3 times
    (scaler and classifier alike); weights of 1 give another model (so the weights are used)."""
    from fastdet.train.fit import fit_classifier

    rng = np.random.default_rng(0)
    x = rng.normal(size=(60, 5)) + np.arange(5)
    y = (x[:, 0] + rng.normal(size=60) > 0.5).astype(np.int64)
    heavy = np.arange(60) < 15
    w = np.where(heavy, 3.0, 1.0)
    s_w, c_w = fit_classifier(x, y, "logreg", 0.5, 0, sample_weight=w)
    rep = np.r_[np.arange(60), np.flatnonzero(heavy), np.flatnonzero(heavy)]
    s_r, c_r = fit_classifier(x[rep], y[rep], "logreg", 0.5, 0)
    np.testing.assert_allclose(s_w.mean_, s_r.mean_, rtol=1e-9)
    np.testing.assert_allclose(s_w.scale_, s_r.scale_, rtol=1e-9)
    np.testing.assert_allclose(c_w.coef_, c_r.coef_, rtol=1e-3, atol=1e-4)
    _, c_1 = fit_classifier(x, y, "logreg", 0.5, 0)
    assert np.abs(c_1.coef_ - c_r.coef_).max() > 1e-2


@pytest.mark.slow
def test_the_camera_crops_are_weighted_not_repeated(data, monkeypatch):
    """fit_camera_model: the camera's crops (and their vehicles' mirror images) join the fit
    once each with weight ``config.weight``, every bundled crop with weight 1, in float32."""
    from fastdet.config import FeatureConfig
    from fastdet.model import Model
    from fastdet.train import fit
    from fastdet.train.dataset import CropSet

    seen = {}
    real = fit.fit_classifier

    def spy(x, y, *a, sample_weight=None, **k):
        seen.update(dtype=x.dtype, y=y.copy(), w=None if sample_weight is None else sample_weight.copy())
        return real(x, y, *a, sample_weight=sample_weight, **k)

    monkeypatch.setattr(fit, "fit_classifier", spy)
    cfg = FeatureConfig(spatial_size=16, hist_bins=16)
    n = cfg.n_features
    bundled = Model(config=cfg, coef=np.zeros(n), intercept=0.0, mean=np.zeros(n), scale=np.ones(n))
    rng = np.random.default_rng(1)
    labels = np.array([1, 1, 0, 0, 0], np.int64)
    camera = CropSet(rng.integers(0, 255, (5, 64, 64, 3), dtype=np.uint8), labels, np.array(["adapt"] * 5),
                     np.arange(5))
    config = AdaptConfig(weight=3, max_per_folder=4, truncate=0.0, reencode=0.0)
    model = adapt.fit_camera_model(data, bundled, camera, config, progress=False, log=lambda s: None)
    w, y = seen["w"], seen["y"]
    assert seen["dtype"] == np.float32 and model.coef.dtype == np.float64
    # bundled crops and their mirror images, then the 5 camera crops and the 2 camera vehicles' mirror images
    n_bundled = len(fit.load_crops(data, max_per_folder=4))
    assert len(y) == len(w) == 2 * n_bundled + 7  # each camera crop once, not 3 times
    assert list(w[-7:]) == [3.0] * 7 and (w[:-7] == 1).all()
    assert list(y[-7:]) == [1, 1, 0, 0, 0, 1, 1]
    assert model.metadata["training"]["extra_weight"] == 3.0


def test_each_mining_round_mines_with_the_model_just_fitted_and_fits_again(monkeypatch):
    """fit_mined_camera_model: round r mines with round r-1's model (seed + r - 1), its crops join
    every later fit, the counts grow by them; a round that finds none ends the rounds."""
    from fastdet.train.dataset import CropSet

    def crops(n: int, tag: str) -> CropSet:
        return CropSet(np.zeros((n, 64, 64, 3), np.uint8), np.zeros(n, np.int64), np.array([tag] * n), np.arange(n))

    fits: list[int] = []
    mined: list[tuple[object, int]] = []

    def fit(data, bundled, c, config, progress=True, log=print):
        fits.append(len(c))
        return f"model{len(fits)}"

    found = {2: 3, 3: 2, 4: 0, 5: 7}

    def mine(pictures, model, config, round_, progress=True):
        mined.append((model, round_))
        return crops(found[round_], f"r{round_}")

    monkeypatch.setattr(adapt, "fit_camera_model", fit)
    monkeypatch.setattr(adapt, "mine_hard_negatives", mine)
    counts = {"hard_negatives": 10}
    model, secs = adapt.fit_mined_camera_model(Path("."), None, [], crops(10, "c"), counts,
                                               AdaptConfig(mining_rounds=5), progress=False, log=lambda s: None)
    assert mined == [("model1", 2), ("model2", 3), ("model3", 4)]  # round 4 finds none: no round 5
    assert fits == [10, 13, 15] and model == "model3" and counts["hard_negatives"] == 15
    assert set(secs) == {"train", "hard_negatives"}
    fits.clear(), mined.clear()
    model, _ = adapt.fit_mined_camera_model(Path("."), None, [], crops(10, "c"), {"hard_negatives": 0},
                                            AdaptConfig(mining_rounds=1), progress=False, log=lambda s: None)
    assert fits == [10] and mined == [] and model == "model1"
    with pytest.raises(ValueError, match="mining_rounds"):
        AdaptConfig(mining_rounds=0)
    # later rounds search at most mining_frames of the pictures, spread evenly
    seen: list[list[int]] = []
    monkeypatch.setattr(adapt, "mine_hard_negatives",
                        lambda pictures, model, config, round_, progress=True: seen.append(list(pictures)))
    adapt.fit_mined_camera_model(Path("."), None, list(range(10)), crops(10, "c"), {"hard_negatives": 0},
                                 AdaptConfig(mining_frames=4), progress=False, log=lambda s: None)
    assert seen == [[0, 3, 6, 9]]
    assert adapt.spread(list(range(5)), 8) == [0, 1, 2, 3, 4] and adapt.spread([7, 8, 9], 1) == [7]


def test_the_cameras_regressor_needs_enough_vehicles(data, monkeypatch):
    """Below MIN_REGRESSOR_VEHICLES vehicles (of 4 px and more) no regressor is fitted: the model
    keeps the bundled one; at the floor one is, on the boxes about those vehicles (and mirrored)."""
    from fastdet.video.refine import load_regressor

    img = data / "test_images" / "test1.jpg"
    cars = np.array([[810.0, 400, 950, 500], [1050, 400, 1270, 510], [600, 400, 602, 450]])  # the last: 2 px wide
    pics = [AnnotatedPicture("t", "cam", f"p{i}", img, 1280, 720, targets=cars) for i in range(3)]
    bundled = load_regressor()
    monkeypatch.setattr(adapt, "MIN_REGRESSOR_VEHICLES", 7)
    reg, report = adapt.fit_camera_regressor(pics, bundled, AdaptConfig(), progress=False)
    assert reg is None and report == {"groups": 6}
    monkeypatch.setattr(adapt, "MIN_REGRESSOR_VEHICLES", 6)
    reg, report = adapt.fit_camera_regressor(pics, bundled, AdaptConfig(), progress=False)
    assert reg is not None and report["groups"] == 6 and report["samples"] == 6 * 2 * 16
    assert reg.spec.n_features == bundled.spec.n_features and not np.array_equal(reg.coef, bundled.coef)


def test_the_cameras_regressor_learns_from_the_models_own_boxes(data, monkeypatch):
    """With own_boxes, each frame's boxes the model found are paired with the vehicle they overlap
    at IoU >= JitterConfig.min_iou (others dropped) and counted own_box_weight times, mirrored too;
    own_box_weight=0 leaves them out (the frames are not even searched)."""
    from fastdet.config import JitterConfig
    from fastdet.video.refine import load_regressor

    img = data / "test_images" / "test1.jpg"
    cars = np.array([[810.0, 400, 950, 500], [1050, 400, 1270, 510]])
    pics = [AnnotatedPicture("t", "cam", f"p{i}", img, 1280, 720, targets=cars) for i in range(3)]
    bundled = load_regressor()
    monkeypatch.setattr(adapt, "MIN_REGRESSOR_VEHICLES", 6)
    seen = []

    def own(frame):
        seen.append(frame.shape)
        return np.array([[820, 410, 900, 490],  # on the first car: IoU 0.46, kept
                         [100, 100, 164, 164],  # on no car
                         [1050, 400, 1100, 450]])  # on the second car, IoU 0.10: dropped

    assert JitterConfig().min_iou == 0.3
    reg, report = adapt.fit_camera_regressor(pics, bundled, AdaptConfig(own_box_weight=4), progress=False,
                                             own_boxes=own)
    assert seen == [(720, 1280, 3)] * 3
    assert report["own_boxes"] == 3 and report["samples"] == 6 * 2 * 16 + 3 * 2 * 4
    seen.clear()
    reg0, report0 = adapt.fit_camera_regressor(pics, bundled, AdaptConfig(own_box_weight=0), progress=False,
                                               own_boxes=own)
    assert seen == [] and report0["own_boxes"] == 0 and report0["samples"] == 6 * 2 * 16
    assert not np.array_equal(reg.coef, reg0.coef)
    with pytest.raises(ValueError, match="own_box_weight"):
        AdaptConfig(own_box_weight=-1)

"""fastdet.train.side: a camera's side-view component -- its positives (the wide targets, jittered
and mirrored), its background and hard negatives, and its fit; and the AdaptConfig fields that
shape it."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from fastdet.boxes import intersection
from fastdet.config import SearchConfig
from fastdet.config.adapt import AdaptConfig
from fastdet.detections import FIRST_COMPONENT_PART
from fastdet.labels.picture import AnnotatedPicture
from fastdet.model import Model, load_model
from fastdet.train import side
from fastdet.train.side import MIN_WIDTH, WINDOW_HEIGHT, count_wide, side_config, side_crops, wide_targets

# test1.jpg: a black car (1.4:1), a white car (2:1), an oncoming car far left (1.6:1), and a
# square box (not wide); test4.jpg: the same two cars a little later
TEST1 = np.array([[810.0, 400, 950, 500], [1050, 400, 1270, 510], [60, 440, 140, 490], [600, 420, 640, 460]])
TEST4 = np.array([[814.0, 410, 940, 490], [1040, 400, 1250, 500]])


@pytest.fixture(scope="module")
def pictures(test_images):
    """Two complete pictures and an incomplete one (its unlabelled vehicles: no background there)."""
    img = {p.name: p for p in test_images}
    return [AnnotatedPicture("t", "cam", "a", img["test1.jpg"], 1280, 720, targets=TEST1),
            AnnotatedPicture("t", "cam", "b", img["test4.jpg"], 1280, 720, targets=TEST4,
                             ignores=np.array([[0.0, 600, 1280, 720]])),
            AnnotatedPicture("t", "cam", "c", img["test1.jpg"], 1280, 720, targets=TEST1, complete=False)]


def test_wide_targets_are_wide_enough_and_big_enough():
    boxes = np.array([[0.0, 0, 140, 100],  # 1.4:1, exactly the aspect: in
                      [0, 0, 139, 100],  # 1.39:1: out
                      [0, 0, 32, 16],  # 32 px wide, exactly the floor: in
                      [0, 0, 31.9, 10],  # 3.19:1 but under 32 px: out
                      [10, 10, 310, 60],  # 6:1: in
                      [0, 0, 50, 50]])  # square: out
    got = wide_targets(boxes, 1.4)
    np.testing.assert_array_equal(got, boxes[[0, 2, 4]])
    assert got.dtype == np.float64 and got.shape == (3, 4)
    assert MIN_WIDTH == 32 and WINDOW_HEIGHT == 32
    np.testing.assert_array_equal(wide_targets(boxes, 2.0), boxes[[2, 4]])
    assert wide_targets(np.zeros((0, 4)), 1.4).shape == (0, 4)
    assert wide_targets([1, 2, 3.0, 2.5], 1.0).shape == (0, 4)  # 2 px wide: under the floor


def test_count_wide_and_side_config(pictures):
    assert count_wide(pictures, 1.4) == 3 + 2 + 3
    assert count_wide(pictures, 1.8) == 1 + 1 + 1
    assert count_wide([], 1.4) == 0
    main = load_model().config
    cfg = side_config(main)
    assert cfg == replace(main, window_height=32) and (cfg.win_w, cfg.win_h) == (64, 32)


def test_side_crops_are_the_wide_targets_jittered_and_mirrored_and_background_of_complete_pictures(pictures):
    cfg = side_config(load_model().config)
    adapt = AdaptConfig(side_jitter=2, side_negatives=7)
    crops = side_crops(pictures, cfg, adapt, progress=False)
    n_pos = 2 * (1 + 2) * count_wide(pictures, 1.4)
    assert crops.images.shape == (n_pos + 2 * 7, 32, 64, 3) and crops.images.dtype == np.uint8
    assert crops.labels.tolist() == [1] * n_pos + [0] * 2 * 7  # no background from the incomplete picture
    assert len(crops.groups) == len(crops.order) == len(crops)
    # each picture's positives, then their mirror images
    start = 0
    for pic in pictures:
        k = (1 + 2) * len(wide_targets(pic.targets, 1.4))
        first, mirrored = crops.images[start:start + k], crops.images[start + k:start + 2 * k]
        np.testing.assert_array_equal(mirrored, first[:, :, ::-1])
        start += 2 * k
    assert start == n_pos
    # the same seed, the same crops; fewer jittered copies, fewer positives; no background asked: none
    again = side_crops(pictures, cfg, adapt, progress=False)
    np.testing.assert_array_equal(again.images, crops.images)
    none = side_crops(pictures, cfg, replace(adapt, side_jitter=0, side_negatives=0), progress=False)
    assert none.labels.tolist() == [1] * 2 * count_wide(pictures, 1.4)
    assert len(side_crops(pictures[2:], cfg, adapt, progress=False).labels) == 2 * 3 * 3  # positives only


def test_hard_negatives_are_the_best_side_windows_touching_no_labelled_box(pictures, monkeypatch):
    """Of every side-view window (an intercept that lets them all through), the best-scoring
    ``per_picture`` of each picture that touch no target or ignore region."""
    main = load_model()
    cfg = side_config(main.config)
    rng = np.random.default_rng(0)
    n = cfg.n_features
    wide = Model(cfg, rng.normal(size=n) * 0.01, 50.0, np.zeros(n), np.ones(n), classifier="logreg")
    carried = replace(main, side=wide)
    seen = []
    real = side.window_crops

    def spy(frames, windows, win_w, win_h, *a, **kw):
        seen.append(np.asarray(windows[0]))
        return real(frames, windows, win_w, win_h, *a, **kw)

    monkeypatch.setattr(side, "window_crops", spy)
    from fastdet.detect import Detector

    search = SearchConfig()
    hard = side.hard_negatives(carried, search, pictures[:2], 6)
    assert hard.images.shape == (12, 32, 64, 3) and hard.labels.tolist() == [0] * 12
    det = Detector(carried, search)
    for pic, boxes in zip(pictures[:2], seen):
        assert boxes.shape == (6, 4)
        labelled = np.concatenate([pic.targets, pic.ignores])
        assert not np.any(intersection(boxes.astype(np.float64), labelled) > 0)
        w = det.detect(pic.load())
        w = w[w.part == FIRST_COMPONENT_PART]
        whole = (w.boxes[:, 0] > 0) & (w.boxes[:, 2] < 1280)  # not clipped at the frame's sides
        assert np.all(w.boxes[whole, 2] - w.boxes[whole, 0] > w.boxes[whole, 3] - w.boxes[whole, 1])  # wide
        clear = ~np.any(intersection(w.boxes.astype(np.float64), labelled) > 0, axis=1)
        assert clear.sum() > 6 and (~clear).sum() > 0
        best = np.sort(w.scores[clear])[::-1][:6]
        got = [w.scores[np.flatnonzero((w.boxes == b).all(axis=1))[0]] for b in boxes]
        np.testing.assert_array_equal(np.sort(got)[::-1], best)


def test_the_side_component_is_fitted_above_its_vehicle_floor(pictures):
    main = load_model()
    search = SearchConfig()
    adapt = AdaptConfig(side_min_vehicles=9, side_jitter=2, side_negatives=20, side_hard=10)
    model, report = side.fit_side_model(pictures, main, search, adapt, progress=False)
    assert model is None and report["vehicles"] == 8 and "fewer than 9" in report["skipped"]
    svc = replace(main, classifier="linearsvc")
    model, report = side.fit_side_model(pictures, svc, search, replace(adapt, side_min_vehicles=8), progress=False)
    assert model is None and report["vehicles"] == 8 and "linearsvc" in report["skipped"]  # logreg main only
    model, report = side.fit_side_model(pictures, main, search, replace(adapt, side_min_vehicles=8),
                                        progress=False)
    assert isinstance(model, Model)
    assert model.config == side_config(main.config) and model.config.window_height == 32
    assert model.classifier == "logreg" and model.side is None and model.regressor is None
    assert report["vehicles"] == 8 and report["positives"] == 2 * 3 * 8 and report["negatives"] == 2 * 20
    assert 0 < report["hard_negatives"] <= 2 * 10 and report["seconds"] >= 0
    assert model.metadata["fit"] == report
    replace(main, side=model)  # a component the main model can carry
    crops = side_crops(pictures, model.config, adapt, progress=False)
    dec = model.decision_function(crops.images)
    pos, neg = dec[crops.labels == 1], dec[crops.labels == 0]
    assert pos.mean() > neg.mean() + 1.0
    assert (pos > 0).mean() > 0.8 and (neg < 0).mean() > 0.8


@pytest.mark.parametrize("bad", [
    {"side_aspect": 0}, {"side_aspect": -1.0}, {"side_aspect": math.inf}, {"side_aspect": math.nan},
    {"side_aspect": "wide"}, {"side_min_vehicles": 0}, {"side_min_vehicles": 2.5}, {"side_min_vehicles": True},
    {"side_jitter": -1}, {"side_negatives": -1}, {"side_hard": -1}, {"side_hard": 1.0},
    {"side_C": 0}, {"side_C": -0.1}, {"side_C": math.inf}, {"side_C": math.nan},
    {"side_offsets": ()}, {"side_offsets": (0.0, math.nan)}, {"side_offsets": (math.inf,)},
    {"side_offsets": ("1",)},
])
def test_adapt_config_refuses_bad_side_settings(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        AdaptConfig(**bad)


def test_adapt_config_side_settings_are_kept_sorted_and_round_trip():
    c = AdaptConfig(side_aspect=1.6, side_min_vehicles=5, side_jitter=0, side_negatives=0, side_hard=0, side_C=0.5,
                    side_offsets=(3, 0, 1.5, 3))
    assert c.side_offsets == (0.0, 1.5, 3.0)
    assert AdaptConfig.from_dict(c.to_dict()) == c
    d = AdaptConfig()
    assert (d.side_aspect, d.side_min_vehicles, d.side_offsets) == (1.4, 20, (0.0, 1.0, 2.0, 3.0, 4.0, 6.0))


def test_no_background_no_side_view_component(pictures):
    """Pictures whose labels are partial give no background crops: nothing to tell a side-on
    vehicle from, so no component (one line of why), not a division by zero."""
    partial = [replace(p, complete=False) for p in pictures]
    model, report = side.fit_side_model(partial, load_model(), SearchConfig(), AdaptConfig(side_min_vehicles=1),
                                        progress=False)
    assert model is None and "no background" in report["skipped"]
    model, report = side.fit_side_model(pictures, load_model(), SearchConfig(),
                                        AdaptConfig(side_min_vehicles=1, side_negatives=0), progress=False)
    assert model is None and "no background" in report["skipped"]


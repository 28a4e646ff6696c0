"""fastdet.train.refine: the pipeline's own boxes as training inputs (matched to their
vehicles), views (jittered, mirrored) and the cascade of regressors fitted each on the boxes
of the ones before it."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.config import FeatureConfig, JitterConfig
from fastdet.detect.regressor import BoxFeatures, BoxRegressor, decode_offsets
from fastdet.train.refine import (
    Samples,
    View,
    collect_samples,
    fit_cascade,
    fit_ridge,
    fit_ridge_cv,
    jittered_views,
    matched_inputs,
    mirror,
    paired_iou,
    step,
    view_samples,
)
from fastdet.video.refine import RefineConfig, refine_boxes

SMALL = FeatureConfig(color_space="YCrCb", hog_channels=(0,), orientations=4, pixels_per_cell=16,
                      cells_per_block=2, spatial_size=4, hist_bins=0)


def test_matched_inputs_pairs_each_box_with_its_best_vehicle() -> None:
    targets = np.array([[0., 0, 100, 50], [200, 0, 260, 40]])
    groups = np.array([7, 8])
    boxes = np.array([[10., 0, 100, 60],   # first vehicle, IoU 0.75
                      [10, 0, 100, 60],    # the same box again: counted once
                      [190, 0, 300, 60],   # second, IoU 0.36
                      [90, 0, 210, 50],    # between them, IoU < 0.2 with both
                      [0, 0, 3, 50]])      # too narrow
    b, t, g = matched_inputs(boxes, targets, groups, 0.3)
    order = np.argsort(b[:, 0])
    np.testing.assert_array_equal(b[order], [[10, 0, 100, 60], [190, 0, 300, 60]])
    np.testing.assert_array_equal(t[order], targets)
    np.testing.assert_array_equal(g[order], [7, 8])
    assert len(matched_inputs(boxes, targets, groups, 0.5)[0]) == 1
    assert len(matched_inputs(np.zeros((0, 4)), targets, groups, 0.3)[0]) == 0
    assert len(matched_inputs(boxes, np.zeros((0, 4)), np.zeros(0), 0.3)[0]) == 0


def test_mirror_flips_image_and_boxes_and_twice_is_identity() -> None:
    img = np.random.default_rng(0).integers(0, 256, (40, 100, 3), dtype=np.uint8)
    v = View(img, np.array([[10., 5, 30, 25]]), np.array([[12., 6, 32, 26]]), np.array([3]))
    m = mirror(v)
    np.testing.assert_array_equal(m.inputs, [[70, 5, 90, 25]])
    np.testing.assert_array_equal(m.targets, [[68, 6, 88, 26]])
    np.testing.assert_array_equal(m.image[:, 0], img[:, -1])
    mm = mirror(m)
    np.testing.assert_array_equal(mm.image, img)
    np.testing.assert_array_equal(mm.inputs, v.inputs)


def _scene(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A noisy frame with three bright 'vehicles' (their boxes and groups)."""
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 60, (240, 400, 3), dtype=np.uint8)
    boxes = np.array([[40., 60, 120, 110], [180, 100, 260, 150], [300, 40, 380, 90]])
    for x1, y1, x2, y2 in boxes.astype(int):
        img[y1:y2, x1:x2] = 200
        img[y1 + 10:y2 - 10, x1 + 10:x2 - 10] = 120
    return img, boxes, np.arange(3) + 10 * seed


def test_jittered_views_and_collect_samples() -> None:
    """Each vehicle gets per_box boxes at IoU >= min_iou in the frame and in its mirror image
    (the same vehicle, flipped); the samples are their features and offsets, reproducible."""
    frames = [_scene(1), _scene(2)]
    jit = JitterConfig(per_box=5, min_iou=0.4)
    views = jittered_views(frames, seed=3, jitter=jit)
    assert len(views) == 4
    for k, v in enumerate(views):
        img, boxes, groups = frames[k // 2]
        want = boxes if k % 2 == 0 else np.stack([400 - boxes[:, 2], boxes[:, 1], 400 - boxes[:, 0], boxes[:, 3]], 1)
        np.testing.assert_array_equal(v.targets, np.repeat(want, 5, 0))
        np.testing.assert_array_equal(v.group, np.repeat(groups, 5))
        assert np.all(paired_iou(v.inputs, v.targets) >= 0.4)
        assert (v.image is img) == (k % 2 == 0)
    assert len(jittered_views(frames, seed=3, jitter=jit, flip=False)) == 2
    coder = BoxFeatures(SMALL, (1.5,))
    smp = collect_samples(frames, coder, seed=3, jitter=jit)
    np.testing.assert_array_equal(smp.boxes, np.concatenate([v.inputs for v in views]))
    np.testing.assert_allclose(decode_offsets(smp.boxes, smp.t), smp.targets, atol=1e-9)
    np.testing.assert_array_equal(smp.x[:5], coder.features(frames[0][0], views[0].inputs[:5]))
    with pytest.raises(ValueError):
        collect_samples([(frames[0][0], np.zeros((0, 4)), np.zeros(0))], coder)


def test_cascade_stages_fit_the_boxes_before_them_and_tighten_them() -> None:
    """Inputs twice as tall as the vehicles (as the heat map's boxes of small cars): each stage
    is fitted on the previous stage's outputs, the training IoU rises stage by stage, and the
    cascade applied by refine_boxes (one stage per step) reproduces those outputs."""
    coder = BoxFeatures(SMALL, (1.5,))
    views = []
    rng = np.random.default_rng(0)
    for s in range(6):
        img, boxes, groups = _scene(s)
        inputs = boxes.copy()
        inputs[:, 1] -= (boxes[:, 3] - boxes[:, 1]) * rng.uniform(0.5, 1.0, 3)
        views.append(View(img, inputs, boxes, groups))
    fits = fit_cascade(views, coder, 2)
    assert len(fits) == 2
    (a1, r1), (a2, r2) = fits
    assert r1["output_mean_iou"] > r1["input_mean_iou"]
    assert r2["input_mean_iou"] == pytest.approx(r1["output_mean_iou"])
    assert r2["output_mean_iou"] >= r2["input_mean_iou"] - 0.01
    regs = [BoxRegressor.from_fit(coder, *a) for a in (a1, a2)]
    cascade = BoxRegressor.stack(regs)
    assert cascade.n_stages == 2
    v = views[0]
    one = step(v.inputs, regs[0].predict(v.image, v.inputs), 0.5, np.log(1.5))
    two = step(one, regs[1].predict(v.image, one), 0.5, np.log(1.5))
    np.testing.assert_allclose(refine_boxes(v.image, v.inputs, cascade, RefineConfig(iterations=2)), two)
    assert paired_iou(two, v.targets).mean() > paired_iou(v.inputs, v.targets).mean()
    with pytest.raises(ValueError):
        fit_cascade(views, coder, 0)


def test_a_views_weight_counts_as_that_many_copies_of_it() -> None:
    """A view of weight 3 fits (two cascade stages: the boxes passed on too) exactly as the same
    view given three times; its features are computed once; weight 0 is refused."""
    coder = BoxFeatures(SMALL, (1.5,))
    rng = np.random.default_rng(1)
    views = []
    for s in range(4):
        img, boxes, groups = _scene(s)
        inputs = boxes + rng.uniform(-3, 3, boxes.shape)
        views.append(View(img, inputs, boxes, groups))
    heavy = View(views[0].image, views[0].inputs, views[0].targets, views[0].group, 3)
    weighted = fit_cascade([heavy] + views[1:], coder, 2)
    copied = fit_cascade([views[0]] * 3 + views[1:], coder, 2)
    for (wa, wr), (ca, cr) in zip(weighted, copied):
        for x, y in zip(wa, ca):
            np.testing.assert_allclose(x, y, rtol=1e-9, atol=1e-12)
        assert wr["samples"] == cr["samples"]
        assert wr["input_mean_iou"] == pytest.approx(cr["input_mean_iou"])
        assert wr["output_mean_iou"] == pytest.approx(cr["output_mean_iou"])
    smp = view_samples([heavy], coder)
    assert len(smp) == 3 * len(heavy.inputs)
    np.testing.assert_array_equal(smp.x[:len(heavy.inputs)], smp.x[len(heavy.inputs):2 * len(heavy.inputs)])
    assert mirror(heavy).weight == 3
    with pytest.raises(ValueError, match="weight"):
        View(heavy.image, heavy.inputs, heavy.targets, heavy.group, 0)


def test_step_clamps_like_refinement() -> None:
    b = np.array([[0., 0, 10, 10]])
    np.testing.assert_allclose(step(b, np.array([[2.0, 0, 3.0, -3.0]]), 0.5, np.log(2.0)),
                               decode_offsets(b, np.array([[0.5, 0, np.log(2.0), -np.log(2.0)]])))


def test_cross_validated_offsets_come_from_fits_without_the_vehicle() -> None:
    """fit_ridge_cv's offsets of a sample are those of the fit on the other folds (at the
    chosen alpha), not of the final fit that saw it."""
    coder = BoxFeatures(SMALL, (1.5,))
    frames = [_scene(s) for s in range(3)]
    smp = view_samples(jittered_views(frames, seed=0, jitter=JitterConfig(per_box=4)), coder)
    alphas = (10.0, 1000.0)
    arrays, report, oof = fit_ridge_cv(smp, coder, alphas, folds=3)
    assert report == fit_ridge(smp, coder, alphas, folds=3)[1]
    groups = np.unique(smp.group)
    fold = np.array([{g: i % 3 for i, g in enumerate(groups)}[g] for g in smp.group])
    te = fold == 0
    sub = Samples(smp.x[~te], smp.t[~te], smp.boxes[~te], smp.targets[~te], smp.group[~te])
    coef, icpt, mean, scale = fit_ridge(sub, coder, (report["alpha"],), folds=2)[0]
    np.testing.assert_allclose(oof[te], np.clip(((smp.x[te] - mean) / scale) @ coef.T + icpt, -1, 1), atol=1e-8)
    full = ((smp.x - arrays[2]) / arrays[3]) @ arrays[0].T + arrays[1]
    assert not np.allclose(oof, np.clip(full, -1, 1))

    with pytest.raises(ValueError, match="features"):  # rows of other features than the coder's
        fit_ridge(smp, BoxFeatures(SMALL, (1.0, 1.5)), alphas)

"""fastdet.train.refine: the pipeline's own boxes as training inputs (matched to their
vehicles), views (jittered, mirrored) and the cascade of regressors fitted each on the boxes
of the ones before it."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.config import FeatureConfig, JitterConfig
from fastdet.detect.regressor import BoxFeatures, BoxRegressor, decode_offsets, encode_offsets, size_features
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


def _size_samples(coder: BoxFeatures, seed: int = 0) -> Samples:
    """Rows whose appearance features are noise and whose offsets depend on the box's width
    alone: boxes under 60 px are 1.4x too wide (as the heat map's on small cars), the others
    right; ``coder``'s size inputs (if any) appended as the pipeline computes them."""
    rng = np.random.default_rng(seed)
    n_app = len(coder.contexts) * coder.config.n_features
    boxes, targets, group = [], [], []
    for g in range(40):
        w = rng.uniform(30, 200)
        for _ in range(8):
            x1, y1 = rng.uniform(0, 1000), rng.uniform(300, 600)
            bw = w * rng.uniform(0.9, 1.1)
            b = np.array([x1, y1, x1 + bw, y1 + 0.6 * bw])
            tw = bw / 1.4 if bw < 60 else bw
            boxes.append(b)
            targets.append([x1 + 0.5 * (bw - tw), y1, x1 + 0.5 * (bw + tw), b[3]])
            group.append(g)
    b, t = np.array(boxes), np.array(targets)
    x = np.concatenate([rng.normal(size=(len(b), n_app)), size_features((720, 1280), b, coder.size_inputs)], axis=1)
    return Samples(x, encode_offsets(b, t), b, t, np.array(group))


def test_size_inputs_let_the_ridge_learn_a_size_dependent_offset() -> None:
    """Offsets that depend on the box's size alone: without size inputs the ridge cannot
    learn them (CV IoU as the boxes were); with a class indicator it can; a size weight
    folds into the stored scale (the penalty on those columns falls by its square), so the
    same regressor arrays predict as fitted."""
    plain = BoxFeatures(SMALL, (1.5,))
    sized = BoxFeatures(SMALL, (1.5,), ("log_width", "width<60"))
    alphas = (1e4,)
    _, rep0 = fit_ridge(_size_samples(plain), plain, alphas)
    smp = _size_samples(sized)
    (coef1, icpt1, mean1, scale1), rep1 = fit_ridge(smp, sized, alphas)
    (coef10, icpt10, mean10, scale10), rep10 = fit_ridge(smp, sized, alphas, size_weight=10.0)
    start = rep0["jittered_mean_iou"]
    assert max(rep0["cv_mean_iou"]) < start + 0.01
    assert max(rep10["cv_mean_iou"]) > max(rep1["cv_mean_iou"]) + 0.02
    assert max(rep10["cv_mean_iou"]) > start + 0.01  # the small boxes (a fifth of the rows) IoU 0.71 -> about 1
    assert rep10["size_inputs"] == ["log_width", "width<60"] and rep10["size_weight"] == 10.0
    assert "size_inputs" not in rep0
    np.testing.assert_allclose(scale10[-2:], scale1[-2:] / 10.0)
    np.testing.assert_array_equal(scale10[:-2], scale1[:-2])
    reg = BoxRegressor.from_fit(sized, coef10, icpt10, mean10, scale10)
    small = smp.boxes[:, 2] - smp.boxes[:, 0] < 60
    pred = reg.predict_features(smp.x)
    assert np.median(pred[small, 2]) < -0.15 and abs(np.median(pred[~small, 2])) < 0.05
    with pytest.raises(ValueError):
        fit_ridge(smp, sized, alphas, size_weight=0.0)
    with pytest.raises(ValueError, match="features"):
        fit_ridge(smp, plain, alphas)


def test_jittered_boxes_may_be_described_by_their_vehicles_size(monkeypatch) -> None:
    """vehicle_size: each jittered box's size inputs are its vehicle's (mirrored with it), its
    appearance features its own; the pipeline's boxes (sizes None) describe themselves, and a
    cascade's later stages keep the sizes the views came with."""
    frames = [_scene(1), _scene(2)]
    jit = JitterConfig(per_box=3, min_iou=0.4)
    coder = BoxFeatures(SMALL, (1.5,), ("log_width", "bottom"))
    views = jittered_views(frames, seed=3, jitter=jit, vehicle_size=True)
    plain = jittered_views(frames, seed=3, jitter=jit)
    for v, p in zip(views, plain):
        np.testing.assert_array_equal(v.inputs, p.inputs)  # the same random boxes
        np.testing.assert_array_equal(v.sizes, v.targets)
        assert p.sizes is None
    np.testing.assert_array_equal(mirror(views[0]).sizes, views[1].targets)
    smp = view_samples(views, coder)
    ref = view_samples(plain, coder)
    np.testing.assert_array_equal(smp.x[:, :-2], ref.x[:, :-2])
    np.testing.assert_allclose(smp.x[:, -2:], size_features((240, 400), smp.targets, coder.size_inputs))
    np.testing.assert_allclose(ref.x[:, -2:], size_features((240, 400), ref.boxes, coder.size_inputs))
    assert not np.allclose(smp.x[:, -2:], ref.x[:, -2:])
    np.testing.assert_array_equal(collect_samples(frames, coder, seed=3, jitter=jit, vehicle_size=True).x, smp.x)
    import fastdet.train.refine as fit_module
    seen = []

    def recording(vs, c):
        seen.append([v.sizes for v in vs])
        return view_samples(vs, c)

    monkeypatch.setattr(fit_module, "view_samples", recording)
    fits = fit_cascade(views, coder, 2)
    assert len(fits) == 2 and fits[0][1]["size_inputs"] == ["log_width", "bottom"]
    assert len(seen) == 2
    for stage in seen:
        for got, v in zip(stage, views):
            np.testing.assert_array_equal(got, v.targets)

"""Training augmentation: truncated crops padded exactly as the detector pads a window over the
frame edge, re-encoded crops, deterministic copies that join only the training part of a split."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.config import FeatureConfig, SearchBand
from fastdet.detect.bands import band_geometry, scaled_band
from fastdet.train import augment
from fastdet.train.augment import (
    MAX_KEEP,
    MIN_KEEP,
    augmented_copies,
    reencode,
    reencode_batch,
    reencode_params,
    truncate,
    truncate_batch,
)


def _crops(n: int, seed: int = 0) -> np.ndarray:
    """Smooth random crops (a JPEG round trip of white noise is not what a car looks like)."""
    import cv2

    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (n, 8, 8, 3), dtype=np.uint8)
    return np.stack([cv2.resize(s, (64, 64), interpolation=cv2.INTER_LINEAR) for s in small])


@pytest.mark.parametrize("keep", [1, 32, 45, 64])
def test_truncate_is_edge_padding(keep):
    crop = np.random.default_rng(keep).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    right = truncate(crop, keep, "right")
    left = truncate(crop, keep, "left")
    for out in (right, left):
        assert out.shape == crop.shape and out.dtype == np.uint8
    np.testing.assert_array_equal(right, np.pad(crop[:, :keep], ((0, 0), (0, 64 - keep), (0, 0)), mode="edge"))
    np.testing.assert_array_equal(left, np.pad(crop[:, 64 - keep:], ((0, 0), (64 - keep, 0), (0, 0)), mode="edge"))
    np.testing.assert_array_equal(right[:, :keep], crop[:, :keep])
    np.testing.assert_array_equal(left[:, 64 - keep:], crop[:, 64 - keep:])
    assert (right[:, keep:] == crop[:, keep - 1: keep]).all()
    assert (left[:, :64 - keep] == crop[:, 64 - keep: 65 - keep]).all()


def test_truncate_rejects_bad_arguments():
    crop = np.zeros((64, 64, 3), np.uint8)
    for keep, side in ((0, "right"), (65, "left"), (32, "top")):
        with pytest.raises(ValueError):
            truncate(crop, keep, side)


@pytest.mark.parametrize("side", ["right", "left"])
def test_truncate_equals_the_detectors_window_over_the_frame_edge(side):
    """A window half over the frame edge, as the detector builds it (border 0.5, replicate),
    is the truncated copy of the crop that would be there if the frame went on."""
    cfg = FeatureConfig()
    rng = np.random.default_rng(1)
    frame = rng.integers(0, 256, (64, 160, 3), dtype=np.uint8)
    band = SearchBand(1.0, 0, 64, 0, None) if side == "right" else SearchBand(1.0, 0, 64, None, 160)
    geo = band_geometry(band, frame.shape[:2], cfg, cells_per_step=1, border=0.5, border_mode="replicate")
    assert (geo.pad_right if side == "right" else geo.pad_left) == 32
    band_px = scaled_band(frame, geo)
    beyond = rng.integers(0, 256, (64, 32, 3), dtype=np.uint8)  # what the camera did not see
    if side == "right":  # the last window: frame columns 128..160, then 32 padded columns
        window = band_px[:, -64:]
        crop = np.concatenate([frame[:, 128:], beyond], axis=1)
    else:  # the first window: 32 padded columns, then frame columns 0..32
        window = band_px[:, :64]
        crop = np.concatenate([beyond, frame[:, :32]], axis=1)
    np.testing.assert_array_equal(window, truncate(crop, 32, side))


def test_truncate_batch_keeps_between_half_and_seven_eighths_and_is_deterministic():
    imgs = _crops(200)
    a = truncate_batch(imgs, np.random.default_rng(5))
    b = truncate_batch(imgs, np.random.default_rng(5))
    np.testing.assert_array_equal(a, b)
    assert a.shape == imgs.shape and a.dtype == np.uint8
    kept, sides = [], set()
    for orig, out in zip(imgs, a):
        same = np.all(out == orig, axis=(0, 2))
        # the kept columns are the crop's own, on one side; the others repeat the edge column
        k_right = int(np.argmin(same)) if not same.all() else 64
        k_left = int(np.argmin(same[::-1])) if not same.all() else 64
        if k_right >= k_left:
            k, side = k_right, "right"
        else:
            k, side = k_left, "left"
        np.testing.assert_array_equal(out, truncate(orig, k, side))
        kept.append(k)
        sides.add(side)
    assert int(np.ceil(MIN_KEEP * 64)) <= min(kept) and max(kept) <= int(MAX_KEEP * 64)
    assert sides == {"left", "right"}


def test_reencode_changes_pixels_a_little_and_is_deterministic():
    imgs = _crops(64)
    a = reencode_batch(imgs, np.random.default_rng(3))
    b = reencode_batch(imgs, np.random.default_rng(3))
    c = reencode_batch(imgs, np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    assert a.shape == imgs.shape and a.dtype == np.uint8
    assert not np.array_equal(a, c)
    diff = np.abs(a.astype(int) - imgs.astype(int)).mean(axis=(1, 2, 3))
    assert (diff > 0).all() and diff.max() < 12  # artefacts, not another picture


def test_reencode_parameters_stay_in_range():
    ps = reencode_params(np.random.default_rng(0), 500, (40, 60))
    assert all(40 <= p.quality <= 60 for p in ps)
    assert all(1.0 <= p.upscale <= augment.MAX_UPSCALE and 0 <= p.blur <= augment.MAX_BLUR for p in ps)
    shifts = np.array([[p.brightness, p.cr, p.cb] for p in ps])
    assert shifts.min() == -augment.MAX_SHIFT and shifts.max() == augment.MAX_SHIFT
    with pytest.raises(ValueError):
        reencode_params(np.random.default_rng(0), 1, (90, 30))


def test_reencode_brightness_shift_only():
    crop = np.full((64, 64, 3), 128, np.uint8)
    p = augment.ReencodeParams(upscale=1.0, quality=100, blur=0.0, brightness=2, cr=0, cb=0)
    out = reencode(crop, p)
    assert abs(float(out.mean()) - 130) < 1.0


def test_augmented_copies_counts_labels_sources_and_seed():
    imgs = _crops(100)
    labels = np.array([1] * 40 + [0] * 60)
    aug = augmented_copies(imgs, labels, seed=0, truncate_fraction=0.5, reencode_fraction=0.25)
    # truncated: 20 vehicles + 30 non-vehicles; re-encoded: 10 + 15
    assert len(aug) == 75 and int(aug.labels.sum()) == 30
    np.testing.assert_array_equal(aug.labels, labels[aug.source])
    assert aug.images.shape == (75, 64, 64, 3) and aug.images.dtype == np.uint8
    only_pos = augmented_copies(imgs, labels, seed=0, truncate_fraction=0.5, truncate_negatives=False)
    assert len(only_pos) == 20 and only_pos.labels.all()
    again = augmented_copies(imgs, labels, seed=0, truncate_fraction=0.5, reencode_fraction=0.25)
    np.testing.assert_array_equal(again.images, aug.images)
    np.testing.assert_array_equal(again.source, aug.source)
    other = augmented_copies(imgs, labels, seed=1, truncate_fraction=0.5, reencode_fraction=0.25)
    assert not np.array_equal(other.source, aug.source)
    none = augmented_copies(imgs, labels, seed=0)
    assert len(none) == 0 and none.images.shape == (0, 64, 64, 3)
    with pytest.raises(ValueError):
        augmented_copies(imgs, labels, seed=0, truncate_fraction=1.5)


def test_only_copies_of_training_crops_join_a_split():
    imgs = _crops(50)
    labels = np.array([1] * 25 + [0] * 25)
    aug = augmented_copies(imgs, labels, seed=0, truncate_fraction=1.0, reencode_fraction=1.0)
    train_idx = np.arange(0, 50, 3)
    sel = aug.in_training(train_idx)
    assert set(aug.source[sel]) <= set(train_idx.tolist())
    assert len(sel) == 2 * len(train_idx)  # every training crop once truncated and once re-encoded
    assert not set(aug.source[np.setdiff1d(np.arange(len(aug)), sel)]) & set(train_idx.tolist())


@pytest.mark.slow
def test_train_never_puts_augmented_copies_in_the_test_part(data, monkeypatch):
    """Each split is fitted on its training crops, their flips and the copies made from them
    only; the test figures are counted on the original crops of the test part."""
    from fastdet.train import fit

    seen = []
    real = fit.fit_classifier

    def spy(x, y, *a, **k):
        seen.append(len(y))
        return real(x, y, *a, **k)

    monkeypatch.setattr(fit, "fit_classifier", spy)
    cfg = FeatureConfig(spatial_size=16, hist_bins=16)
    kw = {"split": "sequence", "seed": 2, "max_per_folder": 20, "refit": False, "progress": False,
          "log": lambda *_: None}
    _, plain = fit.train(data, cfg, **kw)
    _, rep = fit.train(data, cfg, truncate=0.5, reencode=0.5, **kw)
    assert rep["sequence_split"]["n_test"] == plain["sequence_split"]["n_test"]
    assert rep["augment"]["copies"] > 0
    crops = fit.load_crops(data, progress=False, max_per_folder=20)
    tr, _ = fit.sequence_split(crops.groups, crops.order, 2)
    aug = augmented_copies(crops.images, crops.labels, 2, 0.5, True, 0.5)
    assert seen == [2 * len(tr), 2 * len(tr) + len(aug.in_training(tr))]
    assert len(aug.in_training(tr)) < len(aug)  # some copies belong to test crops and were left out

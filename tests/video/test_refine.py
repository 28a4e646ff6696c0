"""Learned box refinement (fastdet.video.refine, fastdet.train.refine): the offset encoding,
the identity of a zero regressor, the file format, and on real frames that it moves boxes
towards the vehicles (a regressor fitted on one clip, checked on the other)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import strategies as st

from fastdet.config import FeatureConfig
from fastdet.detections import Detections
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import read_frames
from fastdet.train.refine import JitterConfig, collect_samples, jitter_boxes, paired_iou
from fastdet.video.refine import (
    REFINE_FEATURES,
    REFINE_MODEL_PATH,
    BoxFeatures,
    BoxRegressor,
    RefineConfig,
    load_regressor,
    refine,
    refine_boxes,
)

SMALL = FeatureConfig(color_space="YCrCb", hog_channels=(0,), orientations=4, pixels_per_cell=16,
                      cells_per_block=2, spatial_size=4, hist_bins=0)

coord = st.floats(-500, 1500, allow_nan=False, allow_infinity=False)
size = st.floats(1, 800, allow_nan=False, allow_infinity=False)
small_offset = st.floats(-2, 2, allow_nan=False, allow_infinity=False)


@st.composite
def boxes(draw) -> np.ndarray:
    x, y, w, h = draw(coord), draw(coord), draw(size), draw(size)
    return np.array([[x, y, x + w, y + h]])


def _frame(seed: int = 0, shape: tuple[int, int] = (180, 320)) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, shape + (3,), dtype=np.uint8)


def test_zero_regressor_is_identity() -> None:
    frame = _frame()
    dets = Detections(np.array([[10, 20, 90, 70], [-8, 100, 40, 190], [200, 10, 330, 60], [5, 5, 9, 9]]),
                      np.array([0.9, 0.5, 0.7, 0.2]), part=np.array([0, 1, 0, 1]), ids=np.array([3, 4, 5, -1]))
    out = refine(frame, dets, BoxRegressor.zero(SMALL, (1.0, 1.5)), RefineConfig(iterations=2))
    np.testing.assert_array_equal(out.boxes, dets.boxes)  # even the boxes over the border
    np.testing.assert_array_equal(out.scores, dets.scores)
    np.testing.assert_array_equal(out.part, dets.part)
    np.testing.assert_array_equal(out.ids, dets.ids)
    assert len(refine(frame, Detections.empty(), BoxRegressor.zero(SMALL))) == 0


def _shift_right(config: FeatureConfig, contexts: tuple[float, ...], tx: float) -> BoxRegressor:
    """A regressor that always predicts a move of ``tx`` widths to the right."""
    reg = BoxRegressor.zero(config, contexts)
    return BoxRegressor(config, reg.contexts, reg.coef, np.array([tx, 0.0, 0.0, 0.0]), reg.mean, reg.scale)


def test_refine_moves_clamps_parts_and_clips() -> None:
    frame = _frame()
    dets = Detections(np.array([[10, 20, 90, 70], [250, 10, 310, 60]]), np.ones(2), part=np.array([0, 1]))
    one = RefineConfig(iterations=1)
    out = refine(frame, dets, _shift_right(SMALL, (1.0,), 0.25), one)
    np.testing.assert_array_equal(out.boxes, [[30, 20, 110, 70], [265, 10, 320, 60]])  # second clipped at W
    out = refine(frame, dets, _shift_right(SMALL, (1.0,), 5.0), RefineConfig(iterations=1, max_shift=0.5))
    np.testing.assert_array_equal(out.boxes[0], [50, 20, 130, 70])  # clamped to half a width
    out = refine(frame, dets, _shift_right(SMALL, (1.0,), 0.25))  # the default: three steps
    np.testing.assert_array_equal(out.boxes[0], [70, 20, 150, 70])  # 0.25 three times
    out = refine(frame, dets, _shift_right(SMALL, (1.0,), 0.25), RefineConfig(parts=(1,)))
    np.testing.assert_array_equal(out.boxes[0], dets.boxes[0])
    out = refine(frame, dets, _shift_right(SMALL, (1.0,), 0.25), RefineConfig(iterations=2))
    np.testing.assert_array_equal(out.boxes[0], [50, 20, 130, 70])  # 0.25 twice
    with pytest.raises(ValueError):
        refine(frame[..., 0], dets, BoxRegressor.zero(SMALL))


def _grow(config: FeatureConfig, tw: float, tx: float = 0.0) -> BoxRegressor:
    """A regressor that always predicts a width change of ``tw`` (log) and a move of ``tx``."""
    reg = BoxRegressor.zero(config, (1.0,))
    return BoxRegressor(config, reg.contexts, reg.coef, np.array([tx, 0.0, tw, 0.0]), reg.mean, reg.scale)


def test_cascade_stopping_and_total_growth_cap() -> None:
    frame = _frame()
    b = np.array([[100.0, 50, 140, 90]])
    # a cascade: step i uses stage i, the last one for the steps after
    cascade = BoxRegressor.stack([_shift_right(SMALL, (1.0,), 0.25), _shift_right(SMALL, (1.0,), 0.5)])
    got = refine_boxes(frame, b, cascade, RefineConfig(iterations=3))
    np.testing.assert_allclose(got, [[100 + 10 + 20 + 20, 50, 140 + 50, 90]])
    with pytest.raises(ValueError):
        BoxRegressor.stack([])
    with pytest.raises(ValueError):
        BoxRegressor.stack([BoxRegressor.zero(SMALL, (1.0,)), BoxRegressor.zero(SMALL, (1.5,))])
    # the width grows by exp(0.2) a step, about the centre; each step's change is capped
    grown = refine_boxes(frame, b, _grow(SMALL, 0.2), RefineConfig(iterations=3))
    np.testing.assert_allclose(grown[0, 2] - grown[0, 0], 40 * np.exp(0.6))
    np.testing.assert_allclose(grown[0, [1, 3]], b[0, [1, 3]])
    capped = refine_boxes(frame, b, _grow(SMALL, 0.2), RefineConfig(iterations=3, max_log_scale=0.1))
    np.testing.assert_allclose(capped[0, 2] - capped[0, 0], 40 * np.exp(0.3))


def test_jitter_boxes() -> None:
    rng = np.random.default_rng(1)
    t = np.array([100.0, 200.0, 200.0, 260.0])
    b = jitter_boxes(t, 50, rng, JitterConfig(min_iou=0.4))
    assert b.shape == (50, 4)
    assert np.all(paired_iou(b, np.repeat(t[None], 50, 0)) >= 0.4)


# ---------------------------------------------------------------------------------------- files


# ---------------------------------------------------------------------------------------- real frames


def _clip(data: Path, clip: str) -> tuple[list[np.ndarray], object]:
    return read_frames(data / "videos" / f"{clip}.mp4"), read_gt(data / "annotations" / f"{clip}.gt.txt")


def _jittered_iou(frames: list[np.ndarray], gt, reg: BoxRegressor, step: int = 4) -> tuple[float, float]:
    """Mean IoU with their vehicles of jittered boxes about every ``step``-th frame's vehicles,
    before and after refinement (fixed seed)."""
    rng = np.random.default_rng(7)
    before, after = [], []
    for f in range(1, len(frames) + 1, step):
        sel = (gt.frames == f) & gt.consider
        for t in gt.boxes[sel]:
            b = jitter_boxes(t, 6, rng, JitterConfig(shift=0.15, scale=(0.8, 1.25), min_iou=0.4))
            tt = np.repeat(t[None], len(b), 0)
            before.extend(paired_iou(b, tt))
            after.extend(paired_iou(refine_boxes(frames[f - 1], b, reg), tt))
    return float(np.mean(before)), float(np.mean(after))


@pytest.mark.skipif(not REFINE_MODEL_PATH.exists(), reason="no shipped regressor")
def test_shipped_regressor_loads_and_tightens_boxes(data: Path) -> None:
    """The shipped regressor (fitted on both clips and the test images: in-sample here, a
    sanity check; the held-out check is the slow test below) moves jittered boxes of
    test_small1's vehicles closer to them."""
    reg = load_regressor()
    assert reg.metadata.get("trained_on")
    frames, gt = _clip(data, "test_small1")
    before, after = _jittered_iou(frames, gt, reg, step=8)
    assert after > before


@pytest.mark.slow
def test_cross_clip_regressor_tightens_held_out_boxes(data: Path) -> None:
    """A regressor fitted on test_video + the test images, never on test_small1, does not
    lower the IoU of boxes about test_small1's vehicles (it raises it)."""
    from tools.scripts.refine_model import annotated, fit_box_regressor, test_images

    frames, gt = _clip(data, "test_video")
    spec = BoxFeatures(REFINE_FEATURES, (1.5,))
    smp = collect_samples(annotated(frames, gt, 1000)[::2] + test_images(), spec, seed=0,
                          jitter=JitterConfig(per_box=8))
    reg = fit_box_regressor(smp, spec)
    assert reg.metadata["fit"]["groups"] == 5
    held, hgt = _clip(data, "test_small1")
    before, after = _jittered_iou(held, hgt, reg, step=4)
    assert after >= before

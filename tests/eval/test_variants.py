"""Camera-shift variants: pixels and ground truth move together; the annotation rules re-applied;
recall by width counts what evaluate() matches."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.detections import Detections
from fastdet.eval.variants import (
    Crop,
    Mirror,
    Resize,
    ShiftY,
    Variant,
    Zoom,
    standard_variants,
    transform_gt,
)

H, W = 180, 320


def _frame_with(box: tuple[int, int, int, int]) -> np.ndarray:
    """A grey gradient frame with a white rectangle at ``box`` (x1, y1, x2, y2, exclusive)."""
    f = np.zeros((H, W, 3), np.uint8)
    f[:] = (np.arange(W) % 50)[None, :, None]
    x1, y1, x2, y2 = box
    f[y1:y2, x1:x2] = 255
    return f


def _white_extent(img: np.ndarray) -> tuple[float, float, float, float]:
    ys, xs = np.nonzero(img[:, :, 0] > 160)
    return xs.min(), ys.min(), xs.max() + 1, ys.max() + 1


VARIANTS = [
    Variant("half", (Resize(160, 90),)),
    Variant("double", (Resize(640, 360),)),
    Variant("zoom", (Zoom(0.6),)),
    Variant("up", (ShiftY(-0.1),)),
    Variant("down", (ShiftY(0.1),)),
    Variant("crop", (Crop(0.1, 0.2),)),
    Variant("mirror", (Mirror(),)),
    Variant("combo", (Zoom(0.8), ShiftY(0.1), Mirror(), Resize(240, 135))),
]


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: v.name)
def test_boxes_move_with_the_pixels(variant):
    box = (100, 60, 180, 100)
    out = variant.frame(_frame_with(box))
    assert out.shape[:2] == variant.out_shape((H, W))
    moved, region = variant.boxes(np.array([box], float), (H, W))
    # the white rectangle's extent in the output is the moved box, to the resampling blur (1 px)
    np.testing.assert_allclose(_white_extent(out), moved[0], atol=1.01)
    assert region[0] >= 0 and region[1] >= 0 and region[2] <= out.shape[1] and region[3] <= out.shape[0]


def test_zoom_fills_by_replication_and_region_is_the_picture():
    v = Variant("z", (Zoom(0.5),))
    f = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    out = v.frame(f)
    _, region = v.boxes(np.zeros((0, 4)), (H, W))
    np.testing.assert_array_equal(region, [80, 45, 240, 135])
    # left of the picture every row repeats its first picture column
    np.testing.assert_array_equal(out[45:135, 0], out[45:135, 80])
    np.testing.assert_array_equal(out[0, 80:240], out[45, 80:240])


def _gt(boxes, consider):
    n = len(boxes)
    return Detections(np.array(boxes, float).reshape(-1, 4), frames=np.ones(n, np.int64), ids=np.arange(n),
                      consider=np.array(consider, bool))


def test_transform_gt_reapplies_the_annotation_rules():
    # frame 720 rows: reference pixels = pixels
    shape = (720, 1280)
    gt = _gt([[1000, 400, 1200, 500],   # 200 wide: cut at 1120 -> 120/200 visible, stays a target
              [1060, 400, 1160, 450],   # cut at 1120 -> 60/100 = 0.6 visible, stays a target
              [1090, 400, 1190, 450],   # cut -> 30/100 visible: becomes an ignore region
              [1150, 400, 1250, 450],   # wholly cut off: dropped
              [100, 400, 160, 440],     # 60 wide: stays
              [500, 400, 530, 420]],    # an ignore region stays one
             [1, 1, 1, 1, 1, 0])
    out = transform_gt(gt, Variant("c", (Crop(0, 0.125),)), shape)
    np.testing.assert_array_equal(out.ids, [0, 1, 2, 4, 5])
    np.testing.assert_array_equal(out.consider, [True, True, False, True, False])
    np.testing.assert_allclose(out.boxes[0], [1000, 400, 1120, 500])
    np.testing.assert_allclose(out.boxes[2], [1090, 400, 1120, 450])


def test_transform_gt_width_rule_in_reference_pixels():
    shape = (720, 1280)
    gt = _gt([[100, 400, 140, 440], [300, 400, 360, 440]], [1, 1])  # 40 and 60 px wide
    # a resolution change keeps a 40-px car a target (same picture)
    for size in ((960, 540), (640, 360), (1920, 1080)):
        out = transform_gt(gt, Variant("r", (Resize(*size),)), shape)
        assert out.consider.tolist() == [True, True]
        np.testing.assert_allclose(out.boxes[0, 2] - out.boxes[0, 0], 40 * size[0] / 1280)
    # a wider lens makes the 40-px car 28 px: an ignore region; 60 -> 42 stays
    out = transform_gt(gt, Variant("z", (Zoom(0.7),)), shape)
    assert out.consider.tolist() == [False, True]


def test_transform_gt_clips_to_the_picture_not_the_fill():
    # shifted down 72 rows: a box at the top edge loses its part above the picture
    gt = _gt([[100, 0, 300, 100]], [1])
    out = transform_gt(gt, Variant("u", (ShiftY(-0.1),)), (720, 1280))
    np.testing.assert_allclose(out.boxes, [[100, 0, 300, 28]])
    assert not out.consider[0]  # 28 of 100 rows left


def test_mirror_gt():
    gt = _gt([[100, 400, 300, 500]], [1])
    out = transform_gt(gt, Variant("m", (Mirror(),)), (720, 1280))
    np.testing.assert_allclose(out.boxes, [[980, 400, 1180, 500]])


def test_standard_variants_names_unique():
    names = [v.name for v in standard_variants()]
    assert len(names) == len(set(names))
    assert {"original", "960x540", "640x360", "1920x1080", "mirror", "x264", "mp4v"} <= set(names)

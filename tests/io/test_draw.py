"""The drawing helpers of the annotated video and of ``image`` (fastdet.io.draw): boxes,
windows coloured by scale and model part, the heat map and label images, debug panels."""
from __future__ import annotations

import numpy as np

from fastdet.detections import ONCOMING_PART, Detections
from fastdet.io import draw


def test_draw_helpers():
    img = np.zeros((100, 200, 3), np.uint8)
    draw.draw_boxes(img, np.array([[10, 20, 60, 80]]), np.array([3.25]))
    assert (img[20:80, 10] == draw.BOX_COLOR).all()
    assert draw.scale_color(1.0) != draw.scale_color(3.0)
    assert draw.scale_color(0.5) == draw.scale_color(1.0) and draw.scale_color(5) == draw.scale_color(3.0)
    heat = np.zeros((25, 50))
    heat[5:10, 5:20] = 3.0
    hi = draw.heat_image(heat)
    assert hi.shape == (25, 50, 3) and hi.dtype == np.uint8 and hi[0, 0].sum() < hi[7, 7].sum()
    big = draw.grid_to_frame(hi, 4, (98, 199))
    assert big.shape == (98, 199, 3) and (big[28, 28] == hi[7, 7]).all()
    labels = np.zeros((25, 50), np.int32)
    labels[5:10, 5:20] = 1
    li = draw.label_image(labels, mask=heat > 0)
    assert (li[7, 7] == draw.label_color(1)).all() and li[0, 0].sum() == 0
    frame = np.zeros((240, 320, 3), np.uint8)
    windows = Detections(np.array([[0, 0, 64, 64]]), np.array([1.0]), scale=np.array([1.0]))
    panels = draw.debug_panels(frame, windows, heat, labels, heat > 0, threshold=2.0)
    assert [p.shape for p in panels] == [(60, 80, 3)] * 3
    draw.paste_panels(frame, panels)
    assert frame[8:68, 8:88].any()


def test_draw_windows_colours_by_scale_and_part():
    """Each window is drawn in the colour of its scale (1 when the column is missing); the
    wide model's windows in that of the negated scale."""
    boxes = np.array([[0, 0, 20, 20], [30, 0, 50, 20], [60, 0, 80, 20]])
    img = np.zeros((40, 100, 3), np.uint8)
    w = Detections(boxes, np.ones(3), scale=np.array([1.0, 3.0, 3.0]), part=np.array([0, 0, ONCOMING_PART]))
    assert draw.draw_windows(img, w, 1) is img
    assert tuple(img[10, 0]) == draw.scale_color(1.0)
    assert tuple(img[10, 30]) == draw.scale_color(3.0)
    assert tuple(img[10, 60]) == draw.scale_color(-3.0)
    assert img[10, 10].sum() == 0  # inside a window: untouched
    img2 = np.zeros((40, 100, 3), np.uint8)
    draw.draw_windows(img2, Detections(boxes, np.ones(3)), 1, scale=0.5)
    assert tuple(img2[5, 9]) == draw.scale_color(1.0) and img2[5, 12].sum() == 0 and img2[15].sum() == 0

"""Sizes in reference pixels: settings written for 1280x720 mean the same picture at any resolution."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.config import HeatConfig
from fastdet.detections import Detections
from fastdet.video.heatmap import HeatMap


@pytest.mark.parametrize("rows", [360, 720, 1080])
def test_heatmap_keeps_the_same_car_at_every_resolution(rows):
    # a car 36 x 24 px at 720 rows (just under min_width 40): dropped at every resolution;
    # one 44 x 24 px: kept at every resolution
    f = rows / 720
    hm = HeatMap((rows, 2 * rows), HeatConfig(n_frames=1, threshold=0.5, extent=0.0, cell=1))
    assert hm.config.min_width == round(40 * f)
    boxes = np.round(np.array([[100, 300, 136, 324], [300, 300, 344, 324]]) * f).astype(np.int32)
    out = hm.update(Detections(boxes, np.full(2, 2.0, np.float32)))
    np.testing.assert_array_equal(out.boxes, boxes[1:])

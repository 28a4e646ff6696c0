"""MainModelCheck: the main model's second look at the small component's boxes, against a slow
reference (the square crop cut and resized by hand, scored crop by crop), and in the pipeline."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.config import PipelineConfig
from fastdet.config.small import SMALL_CHECK
from fastdet.detections import FIRST_COMPONENT_PART, Detections
from fastdet.model import load_model
from fastdet.video import VideoDetector
from fastdet.video.small import MainModelCheck


@pytest.fixture(scope="module")
def frame(test_images):
    return cv2.imread(str(test_images[0]))


def _reference_crop(frame, box, margin, side):
    x1, y1, x2, y2 = box
    half = max(x2 - x1, y2 - y1) * (0.5 + margin)
    cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
    a, c, r, d = (int(np.floor(cx - half)), int(np.ceil(cx + half)), int(np.floor(cy - half)),
                  int(np.ceil(cy + half)))
    big = cv2.copyMakeBorder(frame, 400, 400, 400, 400, cv2.BORDER_REPLICATE)
    reg = big[r + 400: d + 400, a + 400: c + 400]
    interp = cv2.INTER_AREA if reg.shape[0] >= side and reg.shape[1] >= side else cv2.INTER_LINEAR
    return cv2.resize(reg, (side, side), interpolation=interp)


def test_check_scores_the_square_crop_as_the_reference(frame):
    model = load_model()
    chk = MainModelCheck(model, SMALL_CHECK)
    boxes = np.array([[810, 410, 940, 500],  # on test1's white car
                      [1060, 400, 1110, 430],  # a small box
                      [-20, 420, 30, 450],  # over the left edge
                      [200, 100, 248, 148]], float)  # sky
    got = chk.scores(frame, boxes)
    want = [model.decision_function(_reference_crop(frame, b, 0.0625, 64)[None])[0] for b in boxes]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    keep = chk(frame, boxes)
    np.testing.assert_array_equal(keep, np.asarray(want) > SMALL_CHECK)
    assert keep[0] and not keep[3]  # the car passes, the sky does not
    sq = chk.squares(boxes)
    np.testing.assert_allclose(sq[:, 2] - sq[:, 0], sq[:, 3] - sq[:, 1])
    assert chk(frame, np.zeros((0, 4))).shape == (0,)
    with pytest.raises(ValueError, match="margin"):
        MainModelCheck(model, 0.0, margin=-1)


def test_config_checks_small_check():
    assert PipelineConfig().small_check == SMALL_CHECK
    assert PipelineConfig(small_check=None).small_check is None
    for bad in (float("nan"), True, "loose"):
        with pytest.raises(ValueError, match="small_check"):
            PipelineConfig(small_check=bad)  # type: ignore[arg-type]


def test_pipeline_drops_the_small_boxes_the_main_model_rejects(frame):
    from dataclasses import replace

    from fastdet.config import SMALL_MODEL_PATH, SMALL_SEARCH
    from fastdet.detect import Detector

    class Fixed(Detector):  # the pipeline's kind of detector (so the check has its main model), fixed windows
        def __init__(self, dets):
            super().__init__(components=[(SMALL_MODEL_PATH, SMALL_SEARCH)])
            self.dets = dets

        def detect(self, frame, rgb=False, oncoming_bands=None, stats=None, columns=None):
            return self.dets

    sky = [[200, 100, 248, 148]] * 4  # confident small windows on the sky
    car = [[810, 410, 940, 500]] * 4  # and on test1's white car
    boxes = np.array(sky + car)
    dets = Detections(boxes, np.full(8, 0.99, np.float32), scale=np.full(8, 1.5), part=[FIRST_COMPONENT_PART] * 8)
    cfg = PipelineConfig(tracker=None, refine=None, horizon=None, oncoming=False, small=True, plausible=None)
    det = Fixed(dets)
    unchecked = VideoDetector(det, replace(cfg, small_check=None)).update(frame)
    assert len(unchecked) == 2
    out = VideoDetector(det, cfg).update(frame)
    keep = MainModelCheck(det.model, SMALL_CHECK)(frame, unchecked.boxes)
    assert keep.tolist() in ([False, True], [True, False])  # the sky goes, the car stays
    assert len(out) == 1
    np.testing.assert_array_equal(out.boxes[0], unchecked.boxes[keep][0])

"""tools/scripts/gt_crops.py (positives of the bundled oncoming model): one unjittered crop per
annotated box narrower than --max-width, then jittered ones, all 64 x --height."""
from __future__ import annotations

import cv2
import numpy as np

from fastdet.io.motfiles import read_gt
from tools.scripts import gt_crops
from tools.scripts.refine_model import TEST_IMAGES_GT


def test_one_crop_per_box_then_jittered_copies(data, tmp_path, capsys):
    gt = read_gt(TEST_IMAGES_GT)
    w = gt.boxes[:, 2] - gt.boxes[:, 0]
    boxes = int(np.sum(gt.consider & (w <= 100)))
    images = str(data / "test_images" / "test%d.jpg")
    gt_crops.main([images, str(TEST_IMAGES_GT), str(tmp_path / "one"), "--jitter", "1"])
    one = sorted((tmp_path / "one").glob("*.png"))
    assert len(one) == boxes > 0
    assert {cv2.imread(str(p)).shape for p in one} == {(24, 64, 3)}
    gt_crops.main([images, str(TEST_IMAGES_GT), str(tmp_path / "three"), "--jitter", "3", "--height", "32"])
    three = sorted((tmp_path / "three").glob("*.png"))
    assert boxes < len(three) <= 3 * boxes  # jittered crops leaving the frame are skipped
    assert {cv2.imread(str(p)).shape for p in three} == {(32, 64, 3)}
    assert f"wrote {len(three)} crops" in capsys.readouterr().out

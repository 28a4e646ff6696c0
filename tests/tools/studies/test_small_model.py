"""tools/studies/small_model.py: the window figures of one clip from hand-made frames and windows."""
from __future__ import annotations

import numpy as np

from fastdet.train.keyframes import AnnotatedFrame
from tools.studies.small_model import window_stats


def test_window_stats_counts_small_targets_and_false_windows():
    img = np.zeros((720, 1280, 3), np.uint8)
    small = [100, 400, 150, 430]  # 50 px wide: small
    big = [600, 380, 800, 520]  # 200 px wide: not counted as small
    f1 = AnnotatedFrame("c", 1, img, np.array([small, big], float), np.array([[1000, 400, 1040, 420]], float))
    f2 = AnnotatedFrame("c", 2, img, np.zeros((0, 4)), np.zeros((0, 4)))
    w1 = np.array([[100, 395, 150, 435],  # on the small car (IoU 0.71)
                   [98, 398, 148, 433],  # on it too, weaker
                   [650, 400, 690, 440],  # inside the big car: IoU < 0.3 but touching it
                   [300, 300, 340, 340],  # far from everything
                   [1010, 400, 1050, 440]], float)  # on the ignore region
    d1 = np.array([2.5, 0.5, 1.5, 3.5, 9.0])
    w2 = np.array([[10, 10, 50, 50]], float)
    d2 = np.array([0.5])
    r = window_stats([f1, f2], [(w1, d1), (w2, d2)], levels=(0.0, 3.0))
    assert (r["frames"], r["small"], r["reached"]) == (2, 1, 1)
    assert r["positive"] == {0.0: 1, 3.0: 0} and r["median_best"] == 2.5
    # false windows: the one in the big car (touching it), the far one, frame 2's; not the ignore one
    assert r["fw_per_frame"] == {0.0: 3 / 2, 3.0: 1 / 2}
    assert r["clear_per_frame"] == {0.0: 2 / 2, 3.0: 1 / 2}
    assert r["windows_per_frame"] == 3.0
    # a small target no window reaches
    r = window_stats([f1], [(w2, d2)], levels=(0.0,))
    assert (r["small"], r["reached"], r["median_best"]) == (1, 0, None)

"""tools/studies/small_boxes.py: the box measurements (hit, near miss, far false alarm, box /
target size ratios, windows and heat on a target) on a made-up frame."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fastdet.detections import Detections
from tools.studies.small_boxes import fa_summary, measure, summary


@dataclass
class _Clip:
    truth: Detections

    def gt(self) -> Detections:
        return self.truth


def _record(out: list, windows: list) -> dict:
    heat = np.zeros((180, 320))
    heat[50:60, 25:40] = 6.0  # 4-px cells over the first target
    return dict(out=Detections(np.array(out, np.int32).reshape(-1, 4), np.linspace(9, 5, len(out))),
                boxes=Detections(np.array(out, np.int32).reshape(-1, 4), np.ones(len(out))),
                windows=Detections(np.array(windows, np.int32).reshape(-1, 4), np.ones(len(windows))), heat=heat)


def test_hits_near_misses_far_false_alarms_and_ratios() -> None:
    # two targets (a 40x20 and a 100x50 box) and an ignore region, in a 720-row frame
    gt = Detections(np.array([[100., 200, 140, 220], [400, 300, 500, 350], [600, 100, 700, 150]]),
                    frames=np.array([1, 1, 1]), ids=np.array([1, 2, 1000]), consider=np.array([True, True, False]))
    out = [[100, 195, 140, 235],  # first target, twice as tall: IoU 0.5 -> a hit
           [400, 300, 460, 350],  # second target, 60 % of its width: IoU 0.6 -> a hit
           [380, 290, 520, 380],  # second target again (taken): IoU 0.40 -> a near miss
           [600, 100, 700, 150],  # on the ignore region: neither
           [900, 500, 960, 540]]  # nowhere near: a far false alarm
    wins = [[96, 186, 144, 234], [0, 0, 48, 48]]
    m = measure(_Clip(gt), {1: _record(out, wins)}, rows=720, cell=4)
    t1, t2 = m["targets"]
    assert t1["hit"] and t2["hit"]
    assert t1["det"]["hr"] == 2.0 and t1["det"]["wr"] == 1.0 and t1["w"] == 40
    assert t2["det"]["wr"] == 0.6 and t2["det"]["iou"] == 0.6
    assert t1["win"] == 1 and t2["win"] == 0 and t1["peak"] == 6.0 and t2["peak"] == 0.0
    fas = sorted(m["fas"], key=lambda f: f["iou"])
    assert len(fas) == 2 and fas[0]["iou"] == 0.0 and 0.3 <= fas[1]["iou"] < 0.5
    assert fas[1]["tw"] == 100 and fas[1]["hr"] == 90 / 50
    lines = summary("clip", m)
    assert [ln.split(" | ")[1] for ln in lines] == ["<60", "60-120"]
    assert fa_summary("clip", m, 1).startswith("| clip | 2 | 1 | 1 | 1 | 0 | 1 |")


def test_scaled_to_reference_rows() -> None:
    # a 360-row frame: widths in 720-row pixels are twice the frame's
    gt = Detections(np.array([[10., 10, 40, 25]]), frames=np.array([1]), ids=np.array([1]), consider=np.array([True]))
    m = measure(_Clip(gt), {1: _record([], [])}, rows=360, cell=4)
    assert m["targets"][0]["w"] == 60 and m["targets"][0]["h"] == 30 and not m["targets"][0]["hit"]

"""tools/studies/box_fit.py: how each false alarm lies on the target it overlaps most and what
box came nearest to each missed target, on a made-up frame."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fastdet.detections import Detections
from tools.studies.box_fit import count_clip, relation


def test_relation_of_a_box_to_a_target() -> None:
    t = np.array([100, 100, 200, 150])
    assert relation(np.array([110, 105, 150, 145]), t) == "inside"  # half a truck
    assert relation(np.array([80, 90, 260, 170]), t) == "contains"  # a box too big
    assert relation(np.array([150, 100, 250, 150]), t) == "offset"
    assert relation(np.array([300, 100, 350, 150]), t) == "clear"
    assert relation(t, t) == "offset"  # each wholly in the other: neither inside nor containing


@dataclass
class _Clip:
    truth: Detections

    def gt(self) -> Detections:
        return self.truth


@dataclass
class _Run:
    clip: _Clip
    rec: dict
    rows: int


def _dets(boxes: list, ids: list | None = None) -> Detections:
    b = np.array(boxes, np.int32).reshape(-1, 4)
    return Detections(b, np.linspace(9, 5, len(b)).astype(np.float32),
                      ids=None if ids is None else np.array(ids, np.int64))


def test_count_clip_false_alarms_and_misses() -> None:
    # frame 1 (360 rows: reference widths are 2x): targets 1 [100, 100, 200, 150] and
    # 2 [300, 100, 340, 130]; an ignore region [500, 100, 560, 140]
    truth = Detections(np.array([[100, 100, 200, 150], [300, 100, 340, 130], [500, 100, 560, 140]], np.int32),
                       None, frames=np.array([1, 1, 1]), ids=np.array([1, 2, 1000]),
                       consider=np.array([True, True, False]))
    # returned: a hit on target 1, a box over target 2 twice too wide (a false alarm), a
    # box on the ignore region (neither); before the refinement the second box fitted it
    out = _dets([[102, 100, 200, 152], [280, 95, 360, 135], [505, 100, 560, 140]], [7, 8, 9])
    raw = _dets([[100, 100, 200, 150], [300, 100, 341, 131], [505, 100, 560, 140]], [7, 8, 9])
    heat = np.zeros((90, 160))
    heat[25:33, 75:85] = 5.0  # 4-px cells over target 2
    windows = _dets([[298, 98, 342, 132], [100, 100, 150, 150]])
    run = _Run(_Clip(truth), {1: dict(out=raw, windows=windows, heat=heat)}, 360)
    rec = {1: dict(out=out, boxes=_dets([[300, 100, 340, 132]]))}
    fas, misses = count_clip(run, rec)  # type: ignore[arg-type]
    assert len(fas) == 1 and len(misses) == 1
    fa = fas[0]
    assert fa["relation"] == "contains" and fa["target"] == 2 and fa["covers"] == 1
    assert fa["width"] == 160 and fa["wr"] == 2.0 and np.isclose(fa["hr"], 40 / 30)
    assert fa["raw_iou"] > 0.9 and fa["heat_iou"] > 0.9 and not fa["target_hit"]
    m = misses[0]
    assert m["target"] == 2 and m["kind"] == "box misses" and m["relation"] == "contains"
    assert m["windows"] == 1 and m["peak"] == 5.0 and m["raw_iou"] > 0.9

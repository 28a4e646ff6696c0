"""tools/studies/adapt_unlabelled.py: the ensemble's boxes of a clip's kept-aside stretch, and what adapt
chose as its table says it."""
from __future__ import annotations

import numpy as np

from fastdet.data import data_dir
from fastdet.labels.teacher import read_teacher_clip
from tools.studies.adapt_unlabelled import chosen, kept_aside_truth


def test_kept_aside_truth_is_the_ensembles_boxes_from_the_stretch_on():
    data = data_dir()
    clip = "akin_highway"
    every = read_teacher_clip(data / "teacher" / f"{clip}.teacher.txt", video=data / "videos" / f"{clip}.mp4",
                              camera=clip, source="teacher")
    start = every[len(every) // 2].frame
    gt, frames = kept_aside_truth(clip, data, start)
    later = [p for p in every if p.frame >= start]
    assert frames.tolist() == [p.frame for p in later] and frames.min() >= start
    assert int(gt.consider.sum()) == sum(len(p.targets) for p in later)
    assert int((~gt.consider).sum()) == sum(len(p.ignores) for p in later)
    first = later[0]
    np.testing.assert_array_equal(gt.boxes[(gt.frames == first.frame) & gt.consider], first.targets)


def test_the_chosen_column_reads_the_summary():
    new = {"boxes": "nms", "offset": 4.0, "boxes_tried": {
        "nms": {"best_offset": 2.0, "best_f1": 0.6789, "f1_se": 0.0234, "offset": 4.0, "f1": 0.66},
        "heat": {"best_offset": 0.0, "best_f1": 0.5, "f1_se": 0.05, "offset": 1.0, "f1": 0.49}}}
    assert chosen(new) == "nms; 2, 0.68 +- 0.02 -> 4"
    assert chosen({**new, "side": {"fit": {"vehicles": 3}, "offset": None}}) == "nms; 2, 0.68 +- 0.02 -> 4"
    tried = {"fit": {"vehicles": 40}, "offsets_f1": {"0": 0.5, "inf": 0.6}}
    assert chosen({**new, "side": {**tried, "offset": None}}) == "nms; 2, 0.68 +- 0.02 -> 4; side-view left out"
    assert chosen({**new, "side": {**tried, "offset": 3.0}}) == "nms; 2, 0.68 +- 0.02 -> 4; side-view 3"
    assert chosen({"boxes": "heat", "offset": -1.0, "boxes_tried": {"heat": {"offset": -1.0, "f1": 0.4}}}) == "heat, -1"
    assert chosen({"offset": 0.0}) == "heat, 0"

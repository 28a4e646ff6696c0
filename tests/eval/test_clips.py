"""Scoring sparsely annotated clips (evaluate with keyframes) and the per-clip report
(fastdet.eval.clips), on hand-made cases with answers worked out by hand."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fastdet.detections import Detections
from fastdet.errors import DataError
from fastdet.eval import evaluate, format_table
from fastdet.eval.clips import annotated_clips, markdown_table, report_json, score_clip
from fastdet.eval.sizes import REPORT_EDGES, recall_by_width
from fastdet.io.motfiles import parse_gt, parse_predictions


def gt_of(*rows) -> Detections:
    """rows: (frame, id, left, top, width, height, consider)."""
    return parse_gt("\n".join(",".join(str(v) for v in r) + ",1,1" for r in rows), "gt")


def pred_of(*rows) -> Detections:
    """rows: (frame, id, left, top, width, height, conf)."""
    return parse_predictions("\n".join(",".join(str(v) for v in r) + ",-1,-1,-1" for r in rows), "pred")


# keyframes 1, 11, 21: two targets on 1, one (and an ignore region) on 11, none on 21
KF = np.array([1, 11, 21])
NO_PREDS = Detections.from_frames([])  # a clip's predictions: none
GT = gt_of((1, 1, 100, 100, 50, 40, 1), (1, 2, 300, 100, 150, 80, 1),
           (11, 1, 110, 100, 50, 40, 1), (11, 1000, 600, 100, 40, 20, 0))


def test_keyframes_score_listed_frames_only():
    preds = pred_of(
        (1, -1, 100, 100, 50, 40, 0.9),    # hit
        (1, -1, 700, 300, 50, 40, 0.8),    # false alarm on a keyframe
        (5, -1, 100, 100, 50, 40, 0.95),   # not a keyframe: nothing
        (5, -1, 900, 400, 50, 40, 0.95),   # not a keyframe: nothing (would be a false alarm)
        (11, -1, 600, 100, 40, 20, 0.7),   # on the ignore region: dropped
        (21, -1, 10, 10, 50, 40, 0.6),     # a keyframe without lines has no vehicle: false alarm
        (30, -1, 10, 10, 50, 40, 0.6),     # after the last keyframe: nothing
    )
    r = evaluate(GT, preds, keyframes=KF)
    assert (r.frames, r.num_gt, r.num_ignore) == (3, 3, 1)
    assert (r.tp, r.fp, r.fn, r.num_dropped, r.num_outside, r.num_pred) == (1, 2, 2, 1, 3, 4)
    assert r.precision == pytest.approx(1 / 3) and r.recall == pytest.approx(1 / 3)
    assert r.f1 == pytest.approx(2 / (2 + 2 + 2)) and r.fp_per_frame == pytest.approx(2 / 3)
    assert r.ap == pytest.approx(1 / 3)  # the hit ranks first: precision 1 up to recall 1/3
    assert r.keyframes and r.to_dict()["keyframes"] is True
    table = format_table(r)
    assert "3 keyframes" in table and "3 predictions on frames that are not keyframes" in table
    # without keyframes, frames 2..10 and 12..20 would count: frame 5's boxes become false alarms
    dense = evaluate(GT, preds, num_frames=21)
    assert (dense.frames, dense.fp) == (21, 4) and not dense.keyframes


def test_keyframes_refuse_ground_truth_elsewhere_and_bad_arguments():
    with pytest.raises(DataError, match="gt: ground truth on frame 11, which is not one of the keyframes"):
        evaluate(GT, NO_PREDS, keyframes=np.array([1, 21]))
    with pytest.raises(ValueError, match="not both"):
        evaluate(GT, NO_PREDS, keyframes=KF, num_frames=3)
    with pytest.raises(ValueError, match=">= 1"):
        evaluate(GT, NO_PREDS, keyframes=np.array([0, 1, 11]))


def test_id_switches_are_counted_between_keyframes():
    """Tracks are compared keyframe to keyframe: what a tracker did between them is not seen."""
    gt = gt_of((1, 1, 100, 100, 50, 40, 1), (11, 1, 110, 100, 50, 40, 1), (21, 1, 120, 100, 50, 40, 1))
    same = pred_of((1, 7, 100, 100, 50, 40, 0.9), (5, 8, 100, 100, 50, 40, 0.9),
                   (11, 7, 110, 100, 50, 40, 0.9), (21, 7, 120, 100, 50, 40, 0.9))
    r = evaluate(gt, same, keyframes=KF[:3])
    assert (r.id_switches, r.mota, r.idf1) == (0, 1.0, 1.0)
    switched = pred_of((1, 7, 100, 100, 50, 40, 0.9), (11, 8, 110, 100, 50, 40, 0.9),
                       (21, 8, 120, 100, 50, 40, 0.9))
    r = evaluate(gt, switched, keyframes=KF[:3])
    assert r.id_switches == 1 and r.mota == pytest.approx(2 / 3)


def test_recall_by_width_on_keyframes():
    # widths in reference pixels at 360 rows: 100 (60-120) and 300 (>= 120) on frame 1, 100 on 11
    preds = pred_of((1, -1, 300, 100, 150, 80, 0.9), (11, -1, 110, 100, 50, 40, 0.9))
    bins = recall_by_width(GT, preds, frame_rows=360, edges=REPORT_EDGES, keyframes=KF)
    assert [(b.label, b.found, b.total) for b in bins] == [("<60", 0, 0), ("60-120", 1, 2), (">=120", 1, 1)]
    # frame 11 left out when it is not a keyframe (its target is then not counted)
    gt1 = gt_of((1, 1, 100, 100, 50, 40, 1), (1, 2, 300, 100, 150, 80, 1))
    bins = recall_by_width(gt1, preds, frame_rows=360, edges=REPORT_EDGES, keyframes=np.array([1]))
    assert [(b.found, b.total) for b in bins] == [(0, 0), (0, 1), (1, 1)]


def test_score_clip_table_and_json():
    preds = pred_of((1, -1, 100, 100, 50, 40, 0.9), (1, -1, 700, 300, 50, 40, 0.8))
    s = score_clip("cam", GT, preds, frame_rows=720, keyframes=KF)
    assert (s.result.tp, s.result.fp, s.result.frames) == (1, 1, 3)
    # 720 rows: widths 50 (< 60), 150 (>= 120), 50 (< 60)
    assert [(b.found, b.total) for b in s.widths] == [(1, 2), (0, 0), (0, 1)]
    dense = score_clip("dense", gt_of((1, 1, 0, 0, 80, 40, 1)), NO_PREDS, frame_rows=720)
    table = markdown_table([s, dense])
    lines = table.splitlines()
    assert len(lines) == 4 and lines[0].startswith("| clip | frames | targets | P | R | F1 |")
    assert "| cam | 3 kf | 3 | 0.50 | 0.33 | **0.40** |" in lines[2]
    assert lines[2].endswith("| 1/2 | - | 0/1 |")
    assert "| dense | 1 | 1 | n/a | 0.00 | **0.00** |" in lines[3]  # no predictions: precision n/a
    rep = report_json([s, dense], {"horizon": "auto"})
    text = json.dumps(rep, allow_nan=False)  # NaN written as null
    back = json.loads(text)
    assert back["iou"] == 0.5 and back["settings"] == {"horizon": "auto"} and list(back["clips"]) == ["cam", "dense"]
    cam = back["clips"]["cam"]
    assert cam["f1"] == pytest.approx(0.4) and cam["keyframes"] is True and cam["frame_rows"] == 720
    assert cam["recall_by_width"][1] == {"bin": "60-120", "lo": 60.0, "hi": 120.0, "found": 0, "total": 0,
                                         "recall": None}
    assert cam["recall_by_width"][2]["hi"] is None
    assert back["clips"]["dense"]["precision"] is None and math.isnan(dense.result.precision)


def test_annotated_clips_finds_videos_with_ground_truth(tmp_path):
    (tmp_path / "annotations").mkdir()
    (tmp_path / "videos").mkdir()
    for name in ("b", "a", "no_video"):
        (tmp_path / "annotations" / f"{name}.gt.txt").write_text("1,1,0,0,50,40,1,1,1\n")
    for name in ("a", "b", "no_gt"):
        (tmp_path / "videos" / f"{name}.mp4").write_bytes(b"")
    (tmp_path / "annotations" / "b.frames").write_text("1\n5\n")
    clips = annotated_clips(tmp_path)
    assert [c.name for c in clips] == ["a", "b"]
    assert clips[0].keyframes() is None
    np.testing.assert_array_equal(clips[1].keyframes(), [1, 5])
    assert len(clips[1].gt()) == 1 and clips[1].video == tmp_path / "videos" / "b.mp4"


def test_every_shared_clip_scores_its_own_ground_truth_perfectly(data):
    clips = annotated_clips(data)
    names = {c.name for c in clips}
    assert {"test_small1", "test_video", "highway_640", "boston_street", "motorcycle_highway"} <= names
    for clip in clips:
        gt, kf = clip.gt(), clip.keyframes()
        c = gt.consider
        preds = Detections(gt.boxes[c], np.ones(int(c.sum())), ids=gt.ids[c], frames=gt.frames[c])
        s = score_clip(clip.name, gt, preds, frame_rows=720, keyframes=kf)
        assert s.result.f1 == 1.0 and s.result.fp == 0 and s.result.keyframes == (kf is not None), clip.name
        assert sum(b.total for b in s.widths) == s.result.num_gt == sum(b.found for b in s.widths)

"""tools/studies/false_alarms.py: what each returned box is (hit, ignored, near, clear) on the
scored frames, its track's age and life, and the rules tried on a run's boxes."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fastdet.detections import Detections
from fastdet.eval.clips import AnnotatedClip
from tools.studies.false_alarms import RULES, apply_rule, hits, records


def _clip(tmp_path: Path) -> AnnotatedClip:
    ann = tmp_path / "annotations"
    ann.mkdir()
    # frames 1 and 3 are keyframes; on both, a target (id 1) and an ignore region (id 1000)
    lines = [f"{f},1,100,200,100,50,1,1,1\n{f},1000,400,180,60,30,0,1,1\n" for f in (1, 3)]
    (ann / "c.gt.txt").write_text("".join(lines))
    (ann / "c.frames").write_text("1\n3\n")
    return AnnotatedClip("c", tmp_path / "videos" / "c.mp4", ann / "c.gt.txt")


def _dets(boxes: list[list[int]], scores: list[float], ids: list[int]) -> Detections:
    return Detections(np.array(boxes, np.int32).reshape(-1, 4), np.array(scores, np.float32),
                      ids=np.array(ids, np.int64))


def test_records_sort_the_boxes_of_the_scored_frames(tmp_path: Path) -> None:
    clip = _clip(tmp_path)
    frames = [(1, _dets([[100, 200, 200, 250], [150, 200, 260, 260], [600, 300, 650, 340], [405, 182, 455, 208]],
                       [9, 5, 4, 3], [1, 2, 3, 4])),
              (2, _dets([[100, 200, 200, 250], [0, 0, 50, 50]], [9, 1], [1, 5])),  # not a keyframe
              (3, _dets([[102, 200, 202, 250]], [8], [1]))]
    sources = {1: {1: "main", 2: "oncoming", 3: "weak"}}
    recs, targets = records(clip, frames, 0.5, (360, 640), sources)
    kinds = [(r["frame"], r["id"], r["kind"]) for r in recs]
    assert kinds == [(1, 1, "hit"), (1, 2, "near"), (1, 3, "clear"), (1, 4, "ignored"), (3, 1, "hit")]
    r = recs[0]
    assert (r["age"], r["life"], r["source"]) == (1, 3, "main") and recs[-1]["age"] == 3
    assert recs[3]["source"] == "-"
    # widths in 720-row pixels; the bottom 250 is 70 rows below the horizon at 180: ratio 100 / 70
    assert r["width"] == 200.0 and abs(r["dy"] - 70 / 360) < 1e-12 and abs(r["ratio"] - 100 / 70) < 1e-12
    assert recs[2]["ratio"] == 50 / 160 and not r["edge"]
    assert len(targets) == 2 and targets[0]["width"] == 200.0


def test_rules_drop_boxes_and_hits_counts_the_targets_found(tmp_path: Path) -> None:
    clip = _clip(tmp_path)
    frames = [(1, _dets([[100, 200, 200, 250], [104, 200, 204, 252]], [3, 9], [1, 2])),
              (3, _dets([[100, 200, 200, 250]], [8], [1]))]
    assert hits(clip, frames) == {(1, 1), (3, 1)}
    dup = RULES["duplicates IoU > 0.5 (the stage's default)"]
    kept = apply_rule(frames, 0.5, (360, 640), {}, dup)
    assert [d.ids.tolist() for _, d in kept] == [[2], [1]] and hits(clip, kept) == {(1, 1), (3, 1)}
    no_onc = RULES["no box of the oncoming model"]
    kept = apply_rule(frames, 0.5, (360, 640), {1: {2: "oncoming"}, 3: {1: "oncoming"}}, no_onc)
    assert [d.ids.tolist() for _, d in kept] == [[1], []] and hits(clip, kept) == {(1, 1)}
    age = RULES["track returned >= 2 frames"]
    assert [d.ids.tolist() for _, d in apply_rule(frames, 0.5, (360, 640), {}, age)] == [[], [1]]

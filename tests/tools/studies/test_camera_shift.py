"""tools/studies/camera_shift.py: the pooled row of a variant divides its false alarms by the frames
that were scored (a keyframe clip's keyframes), not by every frame of its clips."""
from __future__ import annotations

import math

from tools.studies.camera_shift import pooled


def _row(clip: str, frames: int, scored: int, tp: int, fp: int, fn: int) -> dict:
    return {"variant": "original", "clip": clip, "frames": frames, "scored_frames": scored, "tp": tp, "fp": fp,
            "fn": fn, "ms_per_frame": 10.0, "width_bins": [[0, 60, 1, 2], [60, math.inf, tp - 1, tp + fn - 2]]}


def test_pooled_false_alarms_per_scored_frame() -> None:
    rows = [_row("full", 88, 88, 10, 2, 1), _row("keyframes", 296, 30, 5, 10, 20)]
    p = pooled(rows)
    assert p["frames"] == 384 and p["scored_frames"] == 118
    assert p["fp_per_frame"] == 12 / 118
    assert (p["tp"], p["fp"], p["fn"], p["targets"]) == (15, 12, 21, 36)
    assert p["f1"] == 2 * 15 / (2 * 15 + 12 + 21)
    assert p["width_bins"][0] == [0, 60, 2, 4]

"""The leave-one-camera-out folds and the window table of tools/studies/model_loo.py."""
from __future__ import annotations

import math

from fastdet.train.windows import WindowScore
from tools.studies import model_loo
from tools.studies.loo import Fold, folds

CLIPS = ["boston_street", "highway_640", "motorcycle_highway", "test_small1", "test_video"]


def test_one_fold_per_camera_the_udacity_clips_together():
    fs = folds(CLIPS)
    assert [f.held_out for f in fs] == [("boston_street",), ("highway_640",), ("motorcycle_highway",),
                                        ("test_small1", "test_video")]
    for f in fs:
        assert not set(f.held_out) & set(f.train) and sorted(f.held_out + f.train) == sorted(CLIPS)
    assert fs[-1].name == "test_small1+test_video"
    # a clip alone of its camera group, and no group at all
    assert folds(["test_video", "a"]) == [Fold(("test_video",), ("a",)), Fold(("a",), ("test_video",))]
    assert [f.held_out for f in folds(["a", "b"], same_camera=())] == [("a",), ("b",)]


def test_window_table():
    a = WindowScore(8, 42, 38, {0.1: 0.05, 1.0: 0.19, 10.0: 0.33}, 0.64, 218.25)
    b = WindowScore(8, 42, 38, {0.1: 0.1, 1.0: 0.3, 10.0: 0.5}, 0.7, 12.0)
    t = model_loo.window_table([("boston_street", a, b), ("x", b, None)])
    lines = t.splitlines()
    assert len(lines) == 4 and lines[0].count("|") == lines[2].count("|") == lines[3].count("|")
    assert "0.19 -> **0.30**" in lines[2] and "218.2 -> **12.0**" in lines[2]
    assert "| 0.30 |" in lines[3] and not math.isnan(b.recall_half)


def test_unknown_clip_is_one_line(capsys):
    assert model_loo.main(["--clips", "nope", "--no-train"]) == 2
    assert capsys.readouterr().err.count("\n") == 1

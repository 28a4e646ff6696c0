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


def test_misplaced_counts_boxes_near_a_target_and_clear_of_everything(tmp_path):
    from fastdet.detections import Detections
    from fastdet.eval.clips import AnnotatedClip
    from tools.studies.loo import misplaced

    gt = tmp_path / "c.gt.txt"
    # frame 1: a target at 100,100 50x50 and an ignore region at 300,100 40x40; frame 2 (not a keyframe)
    gt.write_text("1,1,100,100,50,50,1,1,1\n1,1000,300,100,40,40,0,1,1\n2,1,100,100,50,50,1,1,1\n")
    (tmp_path / "c.frames").write_text("1\n")
    clip = AnnotatedClip("c", tmp_path / "c.mp4", gt)
    boxes = [[100, 100, 150, 150],   # a hit
             [90, 90, 200, 200],     # IoU 0.21 with the target: near
             [310, 110, 330, 130],   # on the ignore region: neither
             [500, 10, 550, 60],     # clear
             [500, 10, 550, 60]]     # on frame 2: not scored
    preds = Detections(boxes, [0.9] * 5, frames=[1, 1, 1, 1, 2])
    assert misplaced(clip, preds) == (1, 1)
    (tmp_path / "c.frames").unlink()
    assert misplaced(clip, preds) == (1, 2)


def test_mix_out_of_range_and_a_missing_held_out_regressor_are_one_line(tmp_path, capsys, data):
    import shutil

    import pytest

    from fastdet.model import DEFAULT_MODEL_PATH

    with pytest.raises(SystemExit) as e:
        model_loo.main(["--mix", "1.5", "--no-train", "--work", str(tmp_path)])
    assert e.value.code == 2 and "--mix" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        model_loo.main(["--offset", "nan", "--no-train", "--work", str(tmp_path)])
    assert e.value.code == 2 and "--offset" in capsys.readouterr().err
    shutil.copy(DEFAULT_MODEL_PATH, tmp_path / "main_without_boston_street.npz")
    assert model_loo.main(["--clips", "boston_street", "--no-train", "--no-windows", "--work", str(tmp_path),
                           "--refine-loo", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "refine_without_boston_street.npz" in err


def test_scored_model_blends_with_the_bundled_model():
    import numpy as np

    from fastdet.model import load_model
    from fastdet.train.blend import offset

    bundled = load_model(None)
    other = offset(bundled, 2.0)  # a "held-out model" scoring 2 lower on every window
    model, info = model_loo.scored_model(other, bundled, [], None, 0.25, False)
    crops = np.random.default_rng(0).integers(0, 256, (3, 64, 64, 3), dtype=np.uint8)
    np.testing.assert_allclose(model.decision_function(crops), bundled.decision_function(crops) - 0.5, atol=1e-9)
    assert info == {"mix": 0.25}

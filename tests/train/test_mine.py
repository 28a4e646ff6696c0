"""mine-negatives: false windows are saved at their model's window size; user errors are one line."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.cli import main
from fastdet.train.mine import false_windows


def test_false_windows_rules():
    boxes = np.array([[0, 0, 64, 64], [100, 100, 164, 164], [300, 400, 364, 464]])
    assert false_windows(boxes, x_range=(0, 200)).tolist() == [0, 1]
    assert false_windows(boxes, y_range=(90, 500)).tolist() == [1, 2]
    gt = np.array([[150, 150, 200, 200.0]])  # touches window 1 only
    assert false_windows(boxes, gt_boxes=gt).tolist() == [0, 2]


def test_mine_image_region_writes_64x64_pngs(data, tmp_path, capsys):
    """With a region that holds a car, the car's windows are (wrongly) mined: the rule is
    the user's; we check the mechanics: files, sizes, names."""
    img = data / "test_images" / "test1.jpg"
    out = tmp_path / "neg"
    assert main(["mine-negatives", str(img), "--out", str(out), "--x-range", "780", "1280",
                 "--y-range", "380", "720", "--no-progress"]) == 0
    files = sorted(out.glob("*.png"))
    assert "mined" in capsys.readouterr().out
    assert files, "the cars on the right of test1.jpg fire windows inside that region"
    assert all(cv2.imread(str(f)).shape == (64, 64, 3) for f in files)
    assert files[0].name.startswith("test1_f00001_")


def test_mine_video_with_gt_finds_few(data, tmp_path, capsys):
    out = tmp_path / "neg"
    rc = main(["mine-negatives", str(data / "videos" / "test_video.mp4"), "--gt",
               str(data / "annotations" / "test_video.gt.txt"), "--out", str(out), "--frames", "3",
               "--no-progress"])
    assert rc == 0
    assert "from 3 frames" in capsys.readouterr().out


def test_mine_user_errors(tmp_path, capsys):
    assert main(["mine-negatives", str(tmp_path / "none.mp4"), "--out", str(tmp_path / "o"),
                 "--x-range", "0", "9"]) == 2
    assert "not found" in capsys.readouterr().err
    assert main(["mine-negatives", str(tmp_path / "none.mp4"), "--out", str(tmp_path / "o")]) == 2
    assert "say where there are no vehicles" in capsys.readouterr().err
    assert main(["mine-negatives", str(tmp_path / "none.mp4"), "--out", str(tmp_path / "o"), "--gt", "x",
                 "--part", "oncoming"]) == 2
    assert "--oncoming-model" in capsys.readouterr().err
    assert main(["mine-negatives", str(tmp_path / "none.mp4"), "--out", str(tmp_path / "o"), "--gt", "x",
                 "--part", "wide"]) == 2  # the former name of --part oncoming
    assert "--part oncoming needs --oncoming-model" in capsys.readouterr().err


def test_mine_counts_must_be_positive(tmp_path, capsys):
    for flag, value in (("--every", "0"), ("--frames", "0"), ("--start", "-1")):
        with pytest.raises(SystemExit) as exc:
            main(["mine-negatives", "x.mp4", "--x-range", "0", "9", "--out", str(tmp_path), flag, value])
        assert exc.value.code == 2
        assert "must be >=" in capsys.readouterr().err


def test_mine_image_sequence_with_annotations(data, tmp_path, capsys):
    """``test%d.jpg`` reads the six test images as frames 1..6; with the hand annotations of
    their oncoming cars (tools/test_images.gt.txt), wide windows touching them are not mined."""
    from pathlib import Path

    from fastdet.io.motfiles import read_gt
    from fastdet.model import ONCOMING_MODEL_PATH

    gt_path = Path(__file__).resolve().parents[2] / "tools" / "test_images.gt.txt"
    out = tmp_path / "neg"
    rc = main(["mine-negatives", str(data / "test_images" / "test%d.jpg"), "--gt", str(gt_path), "--out", str(out),
               "--part", "oncoming", "--oncoming-model", str(ONCOMING_MODEL_PATH), "--threshold", "-1",
               "--x-range", "0", "660", "--y-range", "380", "520", "--no-progress"])
    assert rc == 0
    assert "from 6 frames" in capsys.readouterr().out
    files = sorted(out.glob("*.png"))
    assert files and all(cv2.imread(str(f)).shape == (24, 64, 3) for f in files)
    gt = read_gt(gt_path)
    for f in files:  # test_fNNNNN_x_y_w_h.png
        _, fr, x, y, w, h = f.stem.split("_")
        frame, x, y, w, h = int(fr[1:]), int(x), int(y), int(w), int(h)
        box = np.array([x, y, x + w, y + h])
        g = gt.boxes[gt.frames == frame]
        inter_w = np.minimum(box[2], g[:, 2] + 8) - np.maximum(box[0], g[:, 0] - 8)
        inter_h = np.minimum(box[3], g[:, 3] + 8) - np.maximum(box[1], g[:, 1] - 8)
        assert not ((inter_w > 0) & (inter_h > 0)).any(), f.name
    assert main(["mine-negatives", str(data / "test_images" / "nothing%d.jpg"), "--x-range", "0", "9",
                 "--out", str(out)]) == 2
    assert "not found" in capsys.readouterr().err

"""tools/scripts/keyframe_model.py on a small data folder and one keyframe clip: it writes a main
model fastdet loads, recording the clips it learnt from; bad clip names are one line, exit 2."""
from __future__ import annotations

import shutil

import cv2
import pytest

from fastdet.detect import Detector
from fastdet.model import load_model
from tools.scripts import keyframe_model


@pytest.fixture(scope="module")
def small_data(data, tmp_path_factory):
    """Crops (40 + 40) and the boston_street clip with its annotations, linked from the shared folder."""
    root = tmp_path_factory.mktemp("kf_data")
    for sub in ("vehicles", "non-vehicles"):
        folder = sorted(p for p in (data / sub).iterdir() if p.is_dir())[0]
        (root / sub / folder.name).mkdir(parents=True)
        for png in sorted(folder.glob("*.png"))[:40]:
            shutil.copy(png, root / sub / folder.name / png.name)
    for rel in ("videos/boston_street.mp4", "annotations/boston_street.gt.txt", "annotations/boston_street.frames"):
        (root / rel).parent.mkdir(exist_ok=True)
        (root / rel).symlink_to(data / rel)
    return root


def test_builds_a_main_model_from_one_clip(small_data, data, tmp_path, capsys):
    out = tmp_path / "main.npz"
    args = ["--data", str(small_data), "--out", str(out), "--jitter", "0", "--background", "2",
            "--hard-per-frame", "3"]
    assert keyframe_model.main(args) == 0
    m = load_model(out)
    assert (m.config.win_w, m.config.win_h) == (64, 64)
    tr = m.metadata["training"]
    assert tr["keyframes"]["clips"] == ["boston_street"] and tr["keyframes"]["frames"] == 8
    assert tr["command"] == ("python -m tools.scripts.keyframe_model --clips boston_street --jitter 0 "
                             "--background 2 --hard-per-frame 3")
    assert tr["C"] == keyframe_model.TRAINING["C"]
    assert "wrote" in capsys.readouterr().out
    d = Detector(out).detect(cv2.imread(str(data / "test_images" / "test1.jpg")))
    assert len(d.boxes) == len(d.scores)


def test_bad_clips_and_options(small_data, tmp_path, capsys):
    out = tmp_path / "m.npz"
    base = ["--data", str(small_data), "--out", str(out)]
    for extra, words in ((["--clips", "nope"], "nope"), (["--exclude", "boston_street"], "no clip left"),
                         (["--C", "0"], "--C"), (["--max-per-folder", "0"], "--max-per-folder")):
        assert keyframe_model.main(base + extra) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err
    assert keyframe_model.main(["--data", str(small_data), "--out", str(tmp_path / "m.txt")]) == 2
    assert ".npz" in capsys.readouterr().err
    assert not out.exists()

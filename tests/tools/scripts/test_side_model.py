"""tools/scripts/side_model.py (the bundled side-view component), on one keyframe clip with a
small recipe: it writes a model fastdet loads as a component, recording what it learnt from."""
from __future__ import annotations

import cv2

from fastdet.config import side_search
from fastdet.detect import Detector
from fastdet.detections import FIRST_COMPONENT_PART
from fastdet.model import load_model
from tools.scripts import side_model


def test_builds_a_component_from_one_clip(data, tmp_path, capsys):
    out = tmp_path / "side.npz"
    args = ["--clips", "boston_street", "--out", str(out), "--jitter", "0", "--data-negatives", "200",
            "--hard-rounds", "0"]
    assert side_model.main(args) == 0
    m = load_model(out)
    assert (m.config.win_w, m.config.win_h) == (64, 32)
    assert m.metadata["component"]["clips"] == ["boston_street"]
    assert "wrote" in capsys.readouterr().out
    det = Detector(components=[(out, side_search())])
    d = det.detect(cv2.imread(str(data / "test_images" / "test1.jpg")))
    assert set(d.part.tolist()) <= {0, FIRST_COMPONENT_PART}


def test_exclude_and_bad_clips(data, tmp_path, capsys):
    out = tmp_path / "s.npz"
    assert side_model.main(["--clips", "nope", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nope" in err
    assert side_model.main(["--clips", "boston_street", "--exclude", "boston_street", "--out", str(out)]) == 2
    assert "no clip left" in capsys.readouterr().err
    # --exclude takes a list, as keyframe_model's: every name is checked
    assert side_model.main(["--clips", "boston_street", "--exclude", "test_video,nada", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nada" in err and "test_video" not in err.split("(there are")[0]
    assert not out.exists()

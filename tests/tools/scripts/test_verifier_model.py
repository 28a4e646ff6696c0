"""tools/scripts/verifier_model.py (the bundled box verifier) on a few frames of a few teacher
clips: it writes a verifier the picture search loads, recording the command and its
held-out figures; a refit from its cache of first-stage boxes gives the same verifier."""
from __future__ import annotations

import numpy as np

from fastdet.config import PictureSearch
from fastdet.detect.verifier import load_verifier
from fastdet.video.picture import PictureDetector
from tools.scripts import verifier_model

CLIPS = "akin_highway,neeraj_test,orange_road"


def test_builds_a_verifier_and_refuses_bad_options(tmp_path, capsys, test_images):
    import cv2

    out, cache = tmp_path / "v.npz", tmp_path / "c.npz"
    args = ["--clips", CLIPS, "--every", "20", "--folds", "2", "--no-progress", "--cache", str(cache)]
    assert verifier_model.main([*args, "--out", str(out)]) == 0
    v = load_verifier(out)
    meta = v.metadata
    assert meta["command"].startswith("python -m tools.scripts.verifier_model --clips")
    assert meta["first_stage"]["verify"] is False and meta["training"]["cameras"] == 3
    assert meta["training"]["held_out_positives_kept"] >= 0.9
    assert "wrote" in capsys.readouterr().out and cache.is_file()
    # a refit from the cache: the same first-stage boxes, so the same verifier
    again = tmp_path / "again.npz"
    assert verifier_model.main([*args, "--out", str(again)]) == 0
    w = load_verifier(again)
    np.testing.assert_array_equal(w.coef, v.coef)
    assert w.threshold == v.threshold
    # the picture search takes it
    img = cv2.imread(str(test_images[0]))
    d = PictureDetector(config=PictureSearch(), verifier=out).detect(img)
    assert (d.scores > v.threshold).all()
    for bad, message in ((["--every", "0"], "--every must be >= 1"), (["--clips", "nope"], "no teacher clip nope"),
                         (["--keep", "1.5"], "keep_fraction")):
        assert verifier_model.main([*bad, "--out", str(tmp_path / "bad.npz"), "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("verifier_model:") and message in err
    assert not (tmp_path / "bad.npz").exists()

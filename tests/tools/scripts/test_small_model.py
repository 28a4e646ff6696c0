"""tools/scripts/small_model.py (the bundled small-vehicle component) on a tiny copy of the data
set: it writes a 32x32-window model fastdet loads as a component, recording the command."""
from __future__ import annotations

import shutil

import cv2

from fastdet.config import SMALL_SEARCH
from fastdet.detect import Detector
from fastdet.detections import FIRST_COMPONENT_PART
from fastdet.model import load_model
from fastdet.train.dataset import find_pngs
from tools.scripts import small_model


def test_builds_the_component_and_refuses_bad_options(data, tmp_path, capsys):
    tiny = tmp_path / "data"
    for sub in ("vehicles", "non-vehicles"):
        for folder, paths in list(find_pngs(data / sub).items())[:1]:
            (tiny / sub / folder.name).mkdir(parents=True)
            for p in paths[:30]:
                shutil.copy(p, tiny / sub / folder.name / p.name)
    out = tmp_path / "small.npz"
    assert small_model.main(["--data", str(tiny), "--out", str(out), "--tiles", "1", "--part-tiles", "0"]) == 0
    m = load_model(out)
    assert (m.config.win_w, m.config.win_h) == (32, 32)
    meta = m.metadata["small"]
    assert meta["command"].startswith("python -m tools.scripts.small_model --data") and "--tiles 1" in meta["command"]
    assert meta["recipe"]["tiles"] == 1 and meta["recipe"]["part_tiles"] == 0
    assert "wrote" in capsys.readouterr().out
    d = Detector(components=[(out, SMALL_SEARCH)]).detect(cv2.imread(str(data / "test_images" / "test1.jpg")))
    assert set(d.part.tolist()) <= {0, FIRST_COMPONENT_PART}
    bad = tmp_path / "bad.npz"
    assert small_model.main(["--data", str(tiny), "--out", str(bad), "--window", "72"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("small_model:")
    assert not bad.exists()

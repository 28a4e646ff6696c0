"""tools/scripts/zoom_negatives.py (scale-matched negatives of the bundled oncoming model):
--per-crop sub-windows of each non-vehicle crop, resized to 64 x --height."""
from __future__ import annotations

import cv2

from tools.scripts import zoom_negatives


def test_per_crop_sub_windows_of_the_first_crops(data, tmp_path, capsys):
    zoom_negatives.main([str(tmp_path / "z"), "--limit", "4", "--per-crop", "2"])
    out = sorted((tmp_path / "z").glob("*.png"))
    assert len(out) == 8
    assert {cv2.imread(str(p)).shape for p in out} == {(24, 64, 3)}
    assert "wrote 8 crops" in capsys.readouterr().out
    # deterministic for a seed
    zoom_negatives.main([str(tmp_path / "again"), "--limit", "4", "--per-crop", "2"])
    for p in out:
        assert (cv2.imread(str(tmp_path / "again" / p.name)) == cv2.imread(str(p))).all()

"""tools/scripts/oncoming_model.sh (the bundled oncoming-traffic model), run whole on a few
crops of each folder, both mining rounds on two of the six test images: every step runs and
the model it writes is a wide-window model that fastdet loads as the oncoming model."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from fastdet.detect import Detector
from fastdet.model import load_model

REPO = Path(__file__).resolve().parents[3]


@pytest.mark.slow
def test_the_script_builds_a_wide_window_model(data, tmp_path):
    out = tmp_path / "oncoming.npz"
    env = {**os.environ, "FASTDET_DATA": str(data), "ONCOMING_TRAIN_ARGS": "--max-per-folder 25 --split random",
           "ONCOMING_ZOOM_ARGS": "--limit 50", "ONCOMING_MINE_ARGS": "--frames 2"}
    r = subprocess.run(["bash", "tools/scripts/oncoming_model.sh", str(tmp_path / "work"), str(out)], cwd=REPO,
                       env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    for step in ("pos", "zoom", "neg0"):  # the second mining round may find nothing on so small a model
        assert any((tmp_path / "work" / step).glob("*.png")), step
    model = load_model(out)
    assert model.config.window_height == 24  # 64x24 windows: rows 12..36 of the crops
    assert Detector(oncoming=model).oncoming_model is model

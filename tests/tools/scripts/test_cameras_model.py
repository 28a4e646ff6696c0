"""tools/scripts/cameras_model.py on one teacher clip with a small crop set: a loadable model
whose metadata holds the recipe, the rounds and the operating point chosen on held-out frames."""
from __future__ import annotations

import pytest

from fastdet.model import load_model
from tools.scripts import cameras_model


@pytest.mark.slow
def test_cameras_model_on_one_clip(data, tmp_path, capsys):
    out = tmp_path / "pictures.npz"
    rc = cameras_model.main(["--out", str(out), "--data", str(data), "--sets", "teacher:neeraj_test",
                             "--max-per-folder", "15", "--rounds", "1", "--every-other", "4", "--no-progress"])
    assert rc == 0, capsys.readouterr()
    model = load_model(out)
    t = model.metadata["training"]
    assert t["sets"] == ["teacher:neeraj_test"]
    assert len(t["pictures"]["rounds"]) == 1 and t["pictures"]["cameras"] == ["teacher:neeraj_test"]
    point = t["operating_point"]
    assert point["chosen"] in cameras_model.SCORES and point["pictures"] > 0
    assert model.metadata["offset"] == pytest.approx(point["offset"])
    assert point["f1"][str(point["chosen"])] == max(point["f1"].values())


def test_cameras_model_unknown_set_is_one_line(data, tmp_path, capsys):
    assert cameras_model.main(["--out", str(tmp_path / "m.npz"), "--data", str(data), "--sets", "teacher:nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "teacher:nope" in err

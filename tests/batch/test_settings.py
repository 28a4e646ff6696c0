"""fastdet/batch/settings.py: the output files of a video for the settings' kinds; the models
checked before any work."""
from __future__ import annotations

from pathlib import Path

import pytest

from fastdet.batch.settings import SUFFIXES, Settings, checked_settings, output_paths
from fastdet.config import PipelineConfig
from fastdet.errors import ModelError


def test_output_paths_are_the_kinds_asked_for(tmp_path: Path) -> None:
    assert output_paths(tmp_path, "day1_clip", Settings.create()) == {"boxes": tmp_path / "day1_clip.boxes.txt"}
    got = output_paths(str(tmp_path), "c", Settings.create(video=True, json=True))
    assert list(got) == ["boxes", "json", "video"]
    assert got == {k: tmp_path / f"c{SUFFIXES[k]}" for k in got}
    assert [p.name for p in got.values()] == ["c.boxes.txt", "c.boxes.jsonl", "c.annotated.mp4"]


def test_checked_settings_load_the_models_and_refuse_a_file_that_is_not_one(tmp_path: Path) -> None:
    assert checked_settings() == Settings.create()  # the bundled models
    assert checked_settings(video=True, json=True) == Settings.create(video=True, json=True)
    bad = tmp_path / "m.npz"
    bad.write_bytes(b"not a model")
    with pytest.raises(ModelError):
        checked_settings(PipelineConfig(model=str(bad)))
    with pytest.raises(ModelError, match="not found"):
        checked_settings(PipelineConfig(model=str(tmp_path / "none.npz")))
    with pytest.raises(ModelError):
        checked_settings(PipelineConfig(refine_model=str(bad)))


def test_checked_settings_leave_out_the_oncoming_model_a_main_model_records_no_need_for(tmp_path: Path) -> None:
    from fastdet.config import ONCOMING_MODEL_PATH
    from fastdet.model import load_model
    from fastdet.train.blend import offset
    from fastdet.video.detector import ONCOMING_KEY

    own = offset(load_model(), 0.0, metadata={ONCOMING_KEY: False}).save(tmp_path / "own.npz")
    got = checked_settings(PipelineConfig(model=str(own)))
    assert got.pipeline.oncoming is False and got.pipeline.model == str(own.resolve())
    named = checked_settings(PipelineConfig(model=str(own), oncoming=str(ONCOMING_MODEL_PATH)))
    assert named.pipeline.oncoming == str(ONCOMING_MODEL_PATH.resolve())  # a named one still runs
    assert checked_settings().pipeline.oncoming == str(ONCOMING_MODEL_PATH.resolve())


def test_checked_settings_refuse_a_bad_record_of_the_cameras_horizon(tmp_path: Path) -> None:
    """A main model whose record of its camera's horizon is not a fraction of the height is refused
    before any work (one line), not once per video; a good record passes, and a horizon given in
    the settings is not checked against it."""
    from fastdet.model import load_model
    from fastdet.train.blend import offset
    from fastdet.video.detector import HORIZON_KEY

    bad = offset(load_model(), 0.0, metadata={HORIZON_KEY: "low"}).save(tmp_path / "bad.npz")
    good = offset(load_model(), 0.0, metadata={HORIZON_KEY: 0.5}).save(tmp_path / "good.npz")
    with pytest.raises(ModelError, match=HORIZON_KEY):
        checked_settings(PipelineConfig(model=str(bad)))
    assert checked_settings(PipelineConfig(model=str(good))).pipeline.model == str(good.resolve())
    assert checked_settings(PipelineConfig(model=str(bad), horizon=0.5)).pipeline.horizon == 0.5

"""fastdet/batch/settings.py: the output files of a video for the settings' kinds; the models
checked before any work."""
from __future__ import annotations

from pathlib import Path

import pytest

from fastdet.batch.settings import SUFFIXES, Settings, check, output_paths
from fastdet.config import PipelineConfig
from fastdet.errors import ModelError


def test_output_paths_are_the_kinds_asked_for(tmp_path: Path) -> None:
    assert output_paths(tmp_path, "day1_clip", Settings.create()) == {"boxes": tmp_path / "day1_clip.boxes.txt"}
    got = output_paths(str(tmp_path), "c", Settings.create(video=True, json=True))
    assert list(got) == ["boxes", "json", "video"]
    assert got == {k: tmp_path / f"c{SUFFIXES[k]}" for k in got}
    assert [p.name for p in got.values()] == ["c.boxes.txt", "c.boxes.jsonl", "c.annotated.mp4"]


def test_check_loads_the_models_and_refuses_a_file_that_is_not_one(tmp_path: Path) -> None:
    check(Settings.create())  # the bundled models
    bad = tmp_path / "m.npz"
    bad.write_bytes(b"not a model")
    with pytest.raises(ModelError):
        check(Settings.create(PipelineConfig(model=str(bad))))

"""fastdet/config/batch.py: the batch settings' digest covers the model files' contents and the
outputs asked for; a missing model file is refused."""
from __future__ import annotations

import pytest

from fastdet.config import PipelineConfig


def test_batch_settings_hash_the_model_files(tmp_path):
    pytest.importorskip("distributed")
    from fastdet.config.batch import Settings
    from fastdet.config.models import DEFAULT_MODEL_PATH
    from fastdet.errors import ModelError

    copy = tmp_path / "m.npz"
    copy.write_bytes(DEFAULT_MODEL_PATH.read_bytes())
    a = Settings.create(PipelineConfig(model=str(copy)))
    assert a.digest() == Settings.create().digest()  # the same contents elsewhere: the same work
    assert a.pipeline.model == str(copy) and a.record()["model_sha256"] == a.model_sha256
    copy.write_bytes(DEFAULT_MODEL_PATH.read_bytes() + b"\0")
    assert Settings.create(PipelineConfig(model=str(copy))).digest() != a.digest()
    assert Settings.create(video=True).digest() != Settings.create().digest()
    with pytest.raises(ModelError, match="not found"):
        Settings.create(PipelineConfig(oncoming=str(tmp_path / "none.npz")))

"""fastdet/config/models.py: the bundled model files are where the paths say, and a model named
by path is that file, made absolute."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from fastdet.config import models
from fastdet.detect.regressor import load_regressor
from fastdet.model import load_model

MODELS = ["DEFAULT_MODEL_PATH", "ONCOMING_MODEL_PATH"]
REGRESSORS = ["REFINE_MODEL_PATH", "REFINE_UDACITY_MODEL_PATH"]


@pytest.mark.parametrize("name", MODELS)
def test_bundled_models_are_there_and_load(name):
    path = getattr(models, name)
    assert path.parent == models.MODELS_DIR and path.is_file()
    m = load_model(path)
    assert m.coef.shape == (m.config.n_features,)


@pytest.mark.parametrize("name", REGRESSORS)
def test_bundled_regressors_are_there_and_load(name):
    path = getattr(models, name)
    assert path.parent == models.MODELS_DIR and path.is_file()
    load_regressor(path)


def test_resolve_model(tmp_path, monkeypatch):
    bundled = models.DEFAULT_MODEL_PATH
    assert models.resolve_model(None, bundled) == str(bundled)
    monkeypatch.chdir(tmp_path)
    assert models.resolve_model("m.npz", bundled) == str(tmp_path / "m.npz")
    assert models.resolve_model(Path("sub/../w.npz"), bundled) == os.path.join(str(tmp_path), "w.npz")
    assert models.resolve_model(str(bundled), Path("/elsewhere.npz")) == str(bundled)

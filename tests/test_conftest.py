"""tests/conftest.py: a missing data folder or teacher model skips a local run and fails CI."""
from __future__ import annotations

import pytest

from tests import conftest

# either outcome is caught, so that a skip where a failure is due fails this test (uncaught,
# it would only skip it)
OUTCOMES = (pytest.fail.Exception, pytest.skip.Exception)


@pytest.mark.parametrize("ci, outcome", [("true", pytest.fail.Exception), ("", pytest.skip.Exception)])
def test_a_missing_teacher_model_fails_in_ci_and_skips_elsewhere(tmp_path, monkeypatch, ci, outcome):
    monkeypatch.setenv("CI", ci)
    with pytest.raises(OUTCOMES, match="yolox_nano.onnx not found") as e:
        conftest._require_teacher(tmp_path)
    assert e.type is outcome
    (tmp_path / "teachers").mkdir()
    (tmp_path / "teachers" / "yolox_nano.onnx").write_bytes(b"")
    assert conftest._require_teacher(tmp_path) == tmp_path / "teachers" / "yolox_nano.onnx"


@pytest.mark.parametrize("ci, outcome", [("true", pytest.fail.Exception), ("", pytest.skip.Exception)])
def test_a_missing_data_folder_fails_in_ci_and_skips_elsewhere(tmp_path, monkeypatch, ci, outcome):
    monkeypatch.setenv("CI", ci)
    monkeypatch.setenv("FASTDET_DATA", str(tmp_path / "nowhere"))
    with pytest.raises(OUTCOMES, match="data folder .*nowhere not found") as e:
        conftest._require_data()
    assert e.type is outcome

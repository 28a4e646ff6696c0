"""Shared fixtures. The tests need ``../shared/data``: a missing folder skips locally and
fails in CI (``CI=true``)."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from fastdet.data import data_dir


def _require_data() -> Path:
    d = data_dir()
    if not (d / "test_images").is_dir():
        msg = f"data folder {d} not found (set FASTDET_DATA)"
        if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
            pytest.fail(msg)
        pytest.skip(msg)
    return d


@pytest.fixture(scope="session")
def data() -> Path:
    """The shared data folder (``$FASTDET_DATA``)."""
    return _require_data()


@pytest.fixture(scope="session")
def test_images(data: Path) -> list[Path]:
    paths = sorted((data / "test_images").glob("*.jpg"))
    assert paths, "no test images"
    return paths

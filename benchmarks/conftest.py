"""Shared benchmark fixtures. Benchmarks are not part of the default test run; run them
with ``python -m pytest benchmarks/<file> --benchmark-only``."""
from __future__ import annotations

from pathlib import Path

import pytest

from fastdet.data import data_dir


@pytest.fixture(scope="session")
def data() -> Path:
    """The shared data folder (``$FASTDET_DATA``); skips when it is missing."""
    d = data_dir()
    if not (d / "test_images").is_dir():
        pytest.skip(f"data folder {d} not found (set FASTDET_DATA)")
    return d

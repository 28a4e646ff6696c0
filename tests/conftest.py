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


@pytest.fixture(scope="session")
def yolox_nano(data: Path) -> Path:
    """The data folder's teacher CNN, ``teachers/yolox_nano.onnx`` (skipped where it is not)."""
    p = data / "teachers" / "yolox_nano.onnx"
    if not p.exists():
        pytest.skip(f"{p} not found")
    return p


# ------------------------------------------------------------------------- slow tests
# Tests marked ``@pytest.mark.slow`` (several seconds each: training, every window of every
# band against the classic pipeline, ...) are left out of a plain ``pytest`` run; ``--slow``
# runs them too, as does CI (``CI=true``), and so does any explicit ``-m`` expression.


def _ci() -> bool:
    return os.environ.get("CI", "").lower() in ("1", "true", "yes")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--slow", action="store_true", default=False,
                     help="also run the tests marked slow (CI=true does too)")


def _run_slow(config: pytest.Config) -> bool:
    return bool(config.getoption("--slow") or _ci() or config.getoption("markexpr"))


def pytest_report_header(config: pytest.Config) -> str:
    return "slow tests: " + ("included" if _run_slow(config) else "left out (--slow or CI=true runs them)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if _run_slow(config):
        return
    slow = [item for item in items if item.get_closest_marker("slow") is not None]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if item.get_closest_marker("slow") is None]

"""Shared fixtures. The tests need ``../shared/data`` and its teacher model
``teachers/yolox_nano.onnx``: a missing one skips locally and fails in CI (``CI=true``)."""
from __future__ import annotations

import os
from pathlib import Path
from typing import NoReturn

import pytest

from fastdet.data import data_dir


def _missing(msg: str) -> NoReturn:
    """What a missing part of the shared data does: fail in CI (it must be there), else skip."""
    if _ci():
        pytest.fail(msg)
    pytest.skip(msg)


def _require_data() -> Path:
    d = data_dir()
    if not (d / "test_images").is_dir():
        _missing(f"data folder {d} not found (set FASTDET_DATA)")
    return d


def _require_teacher(data: Path) -> Path:
    p = data / "teachers" / "yolox_nano.onnx"
    if not p.exists():
        _missing(f"teacher model {p} not found")
    return p


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
    """The data folder's teacher CNN, ``teachers/yolox_nano.onnx`` (skipped where it is not,
    a failure in CI)."""
    return _require_teacher(data)


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

"""Every runtime import of the package is a declared dependency (issue 33: ``typing_extensions``
was imported at run time but only came in through the test extra's mypy, so a plain
``pip install .`` broke the quick start).

Every ``import`` in ``fastdet/`` is read with ``ast`` (at the top and inside functions; those
under ``if TYPE_CHECKING:`` are for type checkers only and are skipped). A module that is not
in the standard library and not fastdet's own must come from a distribution named in
``[project] dependencies`` -- or, for the optional commands, in the extra that
``OPTIONAL`` names (``batch`` needs ``cluster``, ``label`` / ``adapt`` need ``teacher``).
``.ci/quickstart`` checks the same thing by running the quick start in a fresh environment.
"""
from __future__ import annotations

import ast
import re
import sys
from importlib.metadata import packages_distributions
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "fastdet"

#: top-level module -> the extra it must be declared in (imported only by optional commands)
OPTIONAL = {"distributed": "cluster", "dask": "cluster", "pyarrow": "cluster", "onnxruntime": "teacher"}


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def runtime_imports(source: str) -> set[str]:
    """Top-level names of the absolute imports in ``source`` outside ``if TYPE_CHECKING:``."""
    tree = ast.parse(source)
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            for sub in node.body:
                skip.update(id(n) for n in ast.walk(sub))
    names = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def _normal(dist: str) -> str:
    return re.sub(r"[-_.]+", "-", dist).lower()


def declared() -> tuple[set[str], dict[str, set[str]]]:
    """``(runtime distributions, {extra: distributions})`` from pyproject.toml, normalised."""
    tomllib = pytest.importorskip("tomllib")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]

    def names(reqs: list[str]) -> set[str]:
        return {_normal(re.split(r"[\s<>=!~;\[]", r, maxsplit=1)[0]) for r in reqs}

    extras = {k: names(v) for k, v in project.get("optional-dependencies", {}).items()}
    return names(project["dependencies"]), extras


def third_party_imports() -> dict[str, list[str]]:
    """``{top-level module: [files importing it]}`` for every non-stdlib, non-fastdet import."""
    out: dict[str, list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for name in runtime_imports(path.read_text()):
            if name in sys.stdlib_module_names or name in ("fastdet", "__future__"):
                continue
            out.setdefault(name, []).append(str(path.relative_to(ROOT)))
    return out


def test_runtime_imports_skip_type_checking_blocks() -> None:
    src = ("import os\nimport numpy as np\nfrom typing import TYPE_CHECKING\n"
           "if TYPE_CHECKING:\n    from typing_extensions import Self\n"
           "def f():\n    import cv2\n    from .x import y\n")
    assert runtime_imports(src) == {"os", "numpy", "typing", "cv2"}


def test_every_runtime_import_is_declared() -> None:
    runtime, extras = declared()
    dists = packages_distributions()
    missing = []
    for module, files in sorted(third_party_imports().items()):
        provided = {_normal(d) for d in dists.get(module, [])}
        if not provided:
            missing.append(f"{module} (imported by {files[0]}): no installed distribution provides it")
            continue
        allowed = extras.get(OPTIONAL[module], set()) if module in OPTIONAL else runtime
        if not provided & allowed:
            where = f"the {OPTIONAL[module]!r} extra" if module in OPTIONAL else "[project] dependencies"
            missing.append(f"{module} (imported by {files[0]}; from {sorted(provided)}) is not in {where}")
    assert not missing, "undeclared runtime imports:\n" + "\n".join(missing)

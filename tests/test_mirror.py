"""The tests mirror the package: every module of ``fastdet/`` has a test module in its mirrored
place (``tests/<subpackage>/test_<module>.py`` or ``test_<module>_<aspect>.py``), or a row in
``tests/README.md`` naming the test modules that cover it, which must exist."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def modules() -> list[Path]:
    return sorted(p.relative_to(ROOT) for p in (ROOT / "fastdet").rglob("*.py")
                  if p.name not in ("__init__.py", "__main__.py"))


def mirrored(module: Path) -> list[Path]:
    """The test modules in ``module``'s mirrored place (for a ``_NAME_kernels.py`` module,
    those of its wrapper: ``test_NAME*.py``)."""
    folder = ROOT / "tests" / module.relative_to("fastdet").parent
    name = module.stem.lstrip("_")
    if name.endswith("_kernels"):
        return sorted(folder.glob(f"test_{name.removesuffix('_kernels')}*.py"))
    return sorted(folder.glob(f"test_{name}.py")) + sorted(folder.glob(f"test_{name}_*.py"))


def noted() -> dict[str, list[str]]:
    """``tests/README.md``'s table: module path -> the test modules it names."""
    rows = re.findall(r"(?m)^\| `(fastdet/[^`]+)` \| ([^|]+) \|", (ROOT / "tests" / "README.md").read_text())
    return {m: re.findall(r"`([^`]+)`", tests) for m, tests in rows}


def test_every_module_has_a_mirrored_test_module_or_a_note():
    notes = noted()
    assert len(modules()) > 50
    missing = [str(m) for m in modules() if not mirrored(m) and str(m) not in notes]
    assert not missing, f"no tests/<subpackage>/test_<module>.py and no row in tests/README.md: {missing}"


def test_notes_name_existing_test_modules_of_existing_modules():
    notes = noted()
    assert notes
    for module, tests in notes.items():
        assert (ROOT / module).is_file(), f"tests/README.md names {module}, which does not exist"
        assert tests, module
        for t in tests:
            assert (ROOT / t).is_file(), f"tests/README.md: {module} is tested in {t}, which does not exist"


def test_a_note_is_dropped_once_the_module_has_its_own_test_module():
    stale = [m for m in noted() if mirrored(Path(m))]
    assert not stale, f"these have a mirrored test module now; remove their row from tests/README.md: {stale}"

"""The tests mirror the package (``tools/check_mirror.py``): at least 90% of the public modules
of ``fastdet/`` have a test module in their mirrored place (``tests/<subpackage>/test_<module>.py``
or ``test_<module>_<aspect>.py``); every other module, public or not, has a row in
``tests/README.md`` naming the test modules that cover it, which must exist (or ``none yet``)."""
from __future__ import annotations

import re
from pathlib import Path

from tools import check_mirror
from tools.check_mirror import MIN_RATIO, ROOT, mirrored, modules


def noted() -> dict[str, tuple[list[str], str]]:
    """``tests/README.md``'s table: module path -> (the test modules it names, the cell's text)."""
    rows = re.findall(r"(?m)^\| `(fastdet/[^`]+)` \| ([^|]+) \|", (ROOT / "tests" / "README.md").read_text())
    return {m: (re.findall(r"`([^`]+)`", tests), tests.strip()) for m, tests in rows}


def test_most_public_modules_have_their_mirrored_test_module():
    public = check_mirror.public_modules()
    assert len(public) > 50
    missing = [str(m) for m in check_mirror.unmirrored()]
    assert check_mirror.ratio() >= MIN_RATIO, (
        f"{check_mirror.ratio():.3f} of the public modules have tests/<subpackage>/test_<module>.py, "
        f"below {MIN_RATIO}; missing: {missing}")


def test_the_ratio_counts_public_modules_that_exist(tmp_path):
    for rel in ("fastdet/__init__.py", "fastdet/a.py", "fastdet/_private.py", "fastdet/sub/__init__.py",
                "fastdet/sub/b.py", "fastdet/sub/_b_kernels.py", "fastdet/sub/c.py", "fastdet/_hidden/d.py",
                "tests/sub/test_b_edges.py", "tests/test_a.py", "tests/sub/test_cx.py"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("")
    assert [str(m) for m in check_mirror.public_modules(tmp_path)] == ["fastdet/a.py", "fastdet/sub/b.py",
                                                                       "fastdet/sub/c.py"]
    assert [str(m) for m in check_mirror.unmirrored(tmp_path)] == ["fastdet/sub/c.py"]  # test_cx is not c's
    assert check_mirror.ratio(tmp_path) == 2 / 3
    # a kernel module's tests are its wrapper's
    assert mirrored(Path("fastdet/sub/_b_kernels.py"), tmp_path) == [tmp_path / "tests/sub/test_b_edges.py"]


def test_every_module_has_a_mirrored_test_module_or_a_note():
    notes = noted()
    assert len(modules()) > 50
    missing = [str(m) for m in modules() if not mirrored(m) and str(m) not in notes]
    assert not missing, f"no tests/<subpackage>/test_<module>.py and no row in tests/README.md: {missing}"


def test_notes_name_existing_test_modules_of_existing_modules():
    notes = noted()
    assert notes
    for module, (tests, cell) in notes.items():
        assert (ROOT / module).is_file(), f"tests/README.md names {module}, which does not exist"
        assert tests or cell == "none yet", module
        for t in tests:
            assert (ROOT / t).is_file(), f"tests/README.md: {module} is tested in {t}, which does not exist"


def test_a_note_is_dropped_once_the_module_has_its_own_test_module():
    stale = [m for m in noted() if mirrored(Path(m))]
    assert not stale, f"these have a mirrored test module now; remove their row from tests/README.md: {stale}"

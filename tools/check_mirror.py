"""The tests mirror the package: which modules of ``fastdet/`` have their test module in the
mirrored place, ``tests/<subpackage>/test_<module>.py`` (or ``test_<module>_<aspect>.py``).

A *public* module is one whose dotted name has no part starting with ``_`` (so not
``__init__.py``, ``__main__.py``, the numba ``_*_kernels.py`` modules tested through their
wrappers, nor anything under ``fastdet/_numba/``). The ratio counts the public modules that
exist in this checkout: a new module is counted as soon as it is added, with or without its
tests. ``tests/test_mirror.py`` fails when the ratio drops below :data:`MIN_RATIO`; it also
requires every module without a mirrored test module, public or not, to have a row in
``tests/README.md`` naming the test modules that cover it.

    python -m tools.check_mirror        # the ratio and the public modules without one; exit 1 below MIN_RATIO
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the share of public modules that must have their mirrored test module
MIN_RATIO = 0.90


def modules(root: Path = ROOT) -> list[Path]:
    """Every module of ``fastdet/`` (private ones too) but ``__init__.py`` / ``__main__.py``,
    relative to ``root``."""
    return sorted(p.relative_to(root) for p in (root / "fastdet").rglob("*.py")
                  if p.name not in ("__init__.py", "__main__.py"))


def is_public(module: Path) -> bool:
    """No part of the module's dotted name starts with ``_``."""
    return not any(part.startswith("_") for part in module.with_suffix("").parts)


def public_modules(root: Path = ROOT) -> list[Path]:
    return [m for m in modules(root) if is_public(m)]


def mirrored(module: Path, root: Path = ROOT) -> list[Path]:
    """The test modules in ``module``'s mirrored place (for a ``_NAME_kernels.py`` module,
    those of its wrapper: ``test_NAME*.py``), absolute paths."""
    folder = root / "tests" / Path(module).relative_to("fastdet").parent
    name = Path(module).stem.lstrip("_")
    if name.endswith("_kernels"):
        return sorted(folder.glob(f"test_{name.removesuffix('_kernels')}*.py"))
    return sorted(folder.glob(f"test_{name}.py")) + sorted(folder.glob(f"test_{name}_*.py"))


def unmirrored(root: Path = ROOT) -> list[Path]:
    """The public modules without a mirrored test module."""
    return [m for m in public_modules(root) if not mirrored(m, root)]


def ratio(root: Path = ROOT) -> float:
    """The share of public modules with a mirrored test module (1.0 for none at all)."""
    public = public_modules(root)
    return (len(public) - len(unmirrored(root))) / len(public) if public else 1.0


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args(argv)
    missing = unmirrored()
    n = len(public_modules())
    r = ratio()
    for m in missing:
        print(f"{m}: no tests/{m.relative_to('fastdet').parent / ('test_' + m.stem)}.py")
    print(f"{n - len(missing)} of {n} public modules have their mirrored test module: {r:.2f} "
          f"(at least {MIN_RATIO:.2f} wanted)")
    return 0 if r >= MIN_RATIO else 1


if __name__ == "__main__":
    sys.exit(main())

"""The registry of the numba kernels: every kernel module (:data:`KERNEL_MODULES`), and
each listed signature of a kernel as a :class:`Task` (its argument types, its reference
compile seconds, whether its machine code is cached)."""
from __future__ import annotations

import importlib
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numba

#: every module of numba kernels (each with ``SIGNATURES`` and ``COMPILE_SECONDS``)
KERNEL_MODULES = (
    "fastdet.features._hog_kernels",
    "fastdet.features._window_kernels",
    "fastdet.detect._crop_kernels",
    "fastdet.detect._score_kernels",
    "fastdet.video._heat_kernels",
    "fastdet.video._label_kernels",
    "fastdet.video._motion_kernels",
    "fastdet.video._split_kernels",
)


@dataclass(frozen=True)
class Task:
    """One signature of one kernel: ``module:function:index`` into its ``SIGNATURES`` list."""

    module: str
    name: str
    index: int

    @property
    def key(self) -> str:
        return f"{self.module}:{self.name}:{self.index}"

    @classmethod
    def parse(cls, key: str) -> Task:
        module, name, index = key.rsplit(":", 2)
        return cls(module, name, int(index))

    def dispatcher(self) -> Any:
        return getattr(importlib.import_module(self.module), self.name)

    def signature(self) -> tuple:
        """The argument types, as the tuple a call's dispatch compiles (and caches) under."""
        text = importlib.import_module(self.module).SIGNATURES[self.name][self.index]
        args, _ = numba.core.sigutils.normalize_signature(f"({text},)")
        return tuple(args)

    def reference_seconds(self) -> float:
        """Compile seconds on one core of the reference machine (the kernel's figure shared
        among its signatures)."""
        mod = importlib.import_module(self.module)
        return float(mod.COMPILE_SECONDS.get(self.name, 2.0)) / len(mod.SIGNATURES[self.name])


def tasks_of(kernels: Iterable[Any]) -> list[Task]:
    """Every listed signature of ``kernels`` (Numba dispatchers of the kernel modules)."""
    out = []
    for d in kernels:
        module, name = d.py_func.__module__, d.py_func.__name__
        sigs = importlib.import_module(module).SIGNATURES[name]
        out += [Task(module, name, i) for i in range(len(sigs))]
    return out


def all_kernels() -> list[Any]:
    """The dispatchers of every kernel the package calls (every ``SIGNATURES`` entry)."""
    out = []
    for m in KERNEL_MODULES:
        mod = importlib.import_module(m)
        out += [getattr(mod, name) for name in mod.SIGNATURES]
    return out


def is_cached(task: Task) -> bool:
    """``task``'s machine code is loaded in this process or in the on-disk cache (looked up
    where Numba will look; a stale entry of an edited source does not count)."""
    d = task.dispatcher()
    sig = task.signature()
    if sig in d.overloads:
        return True
    try:
        key = d._cache._index_key(sig, d.targetctx.codegen())
        return key in d._cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - Numba internals changed: compile (a cached kernel then just loads)
        return False

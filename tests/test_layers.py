"""The package's import graph: no cycles, and layers that only point down.

Every ``import`` in every module of ``fastdet/`` (at the top, inside functions, under
``TYPE_CHECKING``: all are dependencies) is read with ``ast``. A module belongs to the
layer of its top-level name (``fastdet.video.heatmap`` -> ``video``), and the layers are
ranked (a layer may import only layers of lower rank; a sub-package may import itself)::

    0  _version, errors, console, signals,     no fastdet imports
       exiting
    1  _numba, data                            numba options, the data folder (may note on the console)
    2  config, boxes, detections               values and arithmetic
    3  features, io                            pixels in, files in and out
    4  model, labels                           a model file and its features; labelled pictures (read through io)
    5  detect, teacher                         one frame (teacher: a CNN detector that labels frames)
    6  video, eval, train                      a stream of frames; scoring; fitting
    7  batch                                   many videos
    8  fastdet (the package __init__)          the public API: re-exports the layers below
    9  cli                                     one module per command
    10 __main__                                ``python -m fastdet``

so nothing but ``cli`` itself and ``__main__`` imports ``cli``. A new top-level module or
sub-package must be given a rank here. Imports between modules of one sub-package may go
either way, but no set of modules may import each other in a cycle (a module importing its
own package, as ``from . import x``, is not counted: the package runs first).
"""
from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "fastdet"

RANKS: dict[str, int] = {
    "_version": 0, "errors": 0, "console": 0, "signals": 0, "exiting": 0,
    "_numba": 1, "data": 1,
    "config": 2, "boxes": 2, "detections": 2,
    "features": 3, "io": 3,
    "model": 4, "labels": 4,
    "detect": 5, "teacher": 5,
    "video": 6, "eval": 6, "train": 6,
    "batch": 7,
    "": 8,  # fastdet/__init__.py
    "cli": 9,
    "__main__": 10,
}


# ------------------------------------------------------------------------- the graph


def read_modules(package_dir: Path) -> dict[str, Path]:
    """``{dotted module name: file}`` for every ``.py`` file under ``package_dir``
    (a package ``__init__`` is named after its package)."""
    root = package_dir.parent
    mods = {}
    for dirpath, _, files in os.walk(package_dir):
        for f in files:
            if f.endswith(".py"):
                p = Path(dirpath) / f
                name = ".".join(p.relative_to(root).with_suffix("").parts)
                mods[name.removesuffix(".__init__")] = p
    return mods


def _resolve(target: str, mods: dict[str, Path]) -> str | None:
    """The longest module name that ``target`` starts with (``None``: not in the package)."""
    while target and target not in mods:
        target = target.rpartition(".")[0]
    return target or None


def import_graph(package_dir: Path) -> dict[str, set[str]]:
    """``{module: modules of the package it imports}``."""
    mods = read_modules(package_dir)
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        pkg = name if path.name == "__init__.py" else name.rpartition(".")[0]
        out = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    parts = pkg.split(".")
                    base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                targets = [f"{base}.{a.name}" for a in node.names] or [base]
            else:
                continue
            for t in targets:
                m = _resolve(t, mods)
                if m is not None and m != name and not name.startswith(m + "."):  # not its own package
                    out.add(m)
        graph[name] = out
    return graph


def layer(module: str) -> str:
    """``fastdet.video.heatmap`` -> ``video``; ``fastdet`` -> ``''``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


# ------------------------------------------------------------------------- the rules


def layer_violations(graph: dict[str, set[str]], ranks: dict[str, int] = RANKS) -> list[str]:
    """Every import that points up or sideways between layers, and every module in no layer."""
    bad = [f"{m}: layer {layer(m)!r} has no rank" for m in sorted(graph) if layer(m) not in ranks]
    for a in sorted(graph):
        for b in sorted(graph[a]):
            la, lb = layer(a), layer(b)
            if la == lb or la not in ranks or lb not in ranks:
                continue
            if ranks[lb] >= ranks[la]:
                bad.append(f"{a} (layer {la or 'fastdet'}, rank {ranks[la]}) imports {b} "
                           f"(layer {lb or 'fastdet'}, rank {ranks[lb]})")
    return bad


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


# ------------------------------------------------------------------------- the package


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(PACKAGE)


def test_the_graph_is_read(graph):
    """Guards the reader itself: known edges of the package are found."""
    assert len(graph) > 40
    assert "fastdet.errors" in graph["fastdet.io.atomic"]          # from ..errors import DataError
    assert "fastdet.detect" in graph["fastdet.video.detector"]     # from ..detect import ...
    assert "fastdet.video.heatmap" in graph["fastdet.video"]       # from .heatmap import HeatMap
    assert "fastdet.cli.main" in graph["fastdet.cli"]
    assert {"fastdet.detect", "fastdet.video"} <= graph["fastdet"]  # the TYPE_CHECKING imports count


def test_no_import_cycles(graph):
    assert cycles(graph) == []


def test_layers_point_down(graph):
    assert layer_violations(graph) == []


def test_nothing_but_cli_and_main_imports_cli(graph):
    users = {a for a, bs in graph.items() for b in bs if layer(b) == "cli"}
    assert {layer(a) for a in users} <= {"cli", "__main__"}, sorted(users)


# ------------------------------------------------------------------------- the rules catch violations


def test_rules_on_synthetic_graphs():
    ok = {
        "fastdet": {"fastdet.detect", "fastdet.config"},
        "fastdet.__main__": {"fastdet.cli"},
        "fastdet.cli": {"fastdet.cli.main"},
        "fastdet.cli.main": {"fastdet.video", "fastdet.errors"},
        "fastdet.video": {"fastdet.video.a"},
        "fastdet.video.a": {"fastdet.video.b", "fastdet.detect"},
        "fastdet.video.b": {"fastdet.boxes"},
        "fastdet.detect": {"fastdet.features", "fastdet.model"},
        "fastdet.io.sink": {"fastdet.detections", "fastdet.boxes", "fastdet.console"},
        "fastdet._numba": {"fastdet.console"},
    }
    assert layer_violations(ok) == [] and cycles(ok) == []
    up = {**ok, "fastdet.features": {"fastdet.video.a"}}
    assert layer_violations(up) == ["fastdet.features (layer features, rank 3) imports fastdet.video.a "
                                    "(layer video, rank 6)"]
    sideways = {**ok, "fastdet.eval.metrics": {"fastdet.video"}}
    assert layer_violations(sideways) == ["fastdet.eval.metrics (layer eval, rank 6) imports fastdet.video "
                                          "(layer video, rank 6)"]
    into_cli = {**ok, "fastdet.batch.task": {"fastdet.cli.main"}}
    assert len(layer_violations(into_cli)) == 1
    facade = {**ok, "fastdet.video.b": {"fastdet"}}  # `from fastdet import X` inside the package
    assert len(layer_violations(facade)) == 1
    base = {**ok, "fastdet.console": {"fastdet._numba"}}  # the lowest layer imports nothing of fastdet
    assert len(layer_violations(base)) == 1 and len(cycles(base)) == 1
    unknown = {**ok, "fastdet.gadgets": set()}
    assert layer_violations(unknown) == ["fastdet.gadgets: layer 'gadgets' has no rank"]
    cyclic = {**ok, "fastdet.video.b": {"fastdet.video.c"}, "fastdet.video.c": {"fastdet.video.a"}}
    assert layer_violations(cyclic) == []  # all inside one sub-package...
    assert cycles(cyclic) == [["fastdet.video.a", "fastdet.video.b", "fastdet.video.c"]]  # ...but a cycle


def test_reader_on_a_synthetic_package(tmp_path):
    """Relative and absolute imports, imports inside functions, and a violation found on disk."""
    files = {
        "fastdet/__init__.py": "from .config import A\n",
        "fastdet/config.py": "A = 1\n",
        "fastdet/detections.py": "",
        "fastdet/features/__init__.py": "from ._hog import hog\n",
        "fastdet/features/_hog.py": "from ..config import A\n\ndef hog():\n    from fastdet.video import run\n",
        "fastdet/video/__init__.py": "from . import pipeline\n",
        "fastdet/video/pipeline.py": "import numpy as np\nfrom .. import detections\nfrom ..features import hog\n"
                                     "from . import helpers\n",
        "fastdet/video/helpers.py": "import fastdet.config\n",
    }
    for rel, text in files.items():
        p = tmp_path / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    g = import_graph(tmp_path / "fastdet")
    assert g == {
        "fastdet": {"fastdet.config"},
        "fastdet.config": set(),
        "fastdet.detections": set(),
        "fastdet.features": {"fastdet.features._hog"},
        "fastdet.features._hog": {"fastdet.config", "fastdet.video"},
        "fastdet.video": {"fastdet.video.pipeline"},
        "fastdet.video.pipeline": {"fastdet.detections", "fastdet.features", "fastdet.video.helpers"},
        "fastdet.video.helpers": {"fastdet.config"},
    }
    assert layer_violations(g) == ["fastdet.features._hog (layer features, rank 3) imports fastdet.video "
                                   "(layer video, rank 6)"]
    # and the cycle it makes: features._hog -> video -> pipeline -> features -> features._hog
    assert cycles(g) == [["fastdet.features", "fastdet.features._hog", "fastdet.video", "fastdet.video.pipeline"]]

"""Where the bundled model files are: the main model, the oncoming-traffic (wide-window) model,
the side-view component and the box regressor. :class:`~fastdet.config.PipelineConfig` names a
model file by path, or ``None`` for the bundled one (:func:`resolve_model`)."""
from __future__ import annotations

import os
from pathlib import Path

#: folder of the bundled model files
MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
#: the bundled main model (64x64 windows)
DEFAULT_MODEL_PATH = MODELS_DIR / "default.npz"
#: the bundled wide-window model for oncoming traffic above the median (``tools/scripts/oncoming_model.sh``)
ONCOMING_MODEL_PATH = MODELS_DIR / "oncoming.npz"
#: the bundled side-view component, 64x32 windows (``python -m tools.scripts.side_model``; docs/components.md)
SIDE_MODEL_PATH = MODELS_DIR / "side.npz"
#: the bundled box regressor (:mod:`fastdet.detect.regressor`)
REFINE_MODEL_PATH = MODELS_DIR / "refine.npz"


def resolve_model(path: str | os.PathLike | None, bundled: Path) -> str:
    """Absolute path of a model file: ``path``, or ``bundled`` for ``None``."""
    return str(bundled) if path is None else os.path.abspath(path)

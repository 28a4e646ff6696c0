"""Where the bundled model files are: the main model, the oncoming-traffic (wide-window) model,
and the box regressor.
:class:`~fastdet.config.PipelineConfig` names a model file by path, or ``None`` for the bundled
one (:func:`resolve_model`)."""
from __future__ import annotations

import os
from pathlib import Path

#: folder of the bundled model files
MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
#: the bundled main model (64x64 windows)
DEFAULT_MODEL_PATH = MODELS_DIR / "default.npz"
#: the bundled wide-window model for oncoming traffic above the median (``tools/scripts/oncoming_model.sh``)
ONCOMING_MODEL_PATH = MODELS_DIR / "oncoming.npz"
#: the bundled box regressor (:mod:`fastdet.detect.regressor`), applied
#: ``RefineConfig.iterations`` (3) times: fitted on test_video, the three keyframe clips of other
#: cameras and the test images, never on test_small1, on boxes jittered about their vehicles and
#: on the pipeline's own boxes (``python -m tools.studies.refine_loo --inputs both --own-repeat 8
#: --refine iterations=3 --ship``; its leave-one-camera-out figures are in its metadata and
#: docs/geometry.md)
REFINE_MODEL_PATH = MODELS_DIR / "refine_cameras.npz"
#: the earlier box regressor, fitted on test_video and the test images alone
#: (``tools/scripts/refine_model.py``); meant for one iteration: ``RefineConfig(iterations=1)``
REFINE_UDACITY_MODEL_PATH = MODELS_DIR / "refine.npz"
#: the bundled box verifier of the single-picture search (:mod:`fastdet.detect.verifier`): trained
#: on the first stage's boxes on the 17 teacher-labelled clips of the data folder, no human label
#: (``python -m tools.scripts.verifier_model``; docs/accuracy.md)
VERIFIER_MODEL_PATH = MODELS_DIR / "verifier.npz"


def resolve_model(path: str | os.PathLike | None, bundled: Path) -> str:
    """Absolute path of a model file: ``path``, or ``bundled`` for ``None``."""
    return str(bundled) if path is None else os.path.abspath(path)

"""The box verifier: a second, stronger look at each box the first stage found (the cascade's
second stage, as in Viola-Jones and DPM's cascades), so that the first stage can keep weak
windows without their false alarms reaching the user.

The first stage (the window model, then NMS and the box regressor) scores windows by their own
64x64 crop; the verifier scores the **refined box** with what the window model does not see:
the box and its surroundings (contexts 1.0 and 1.5 of its size, each resized to 64x64 and
described by the box regressor's features, :func:`fastdet.detect.regressor.box_features`:
luma HOG and an 8x8 colour thumbnail), plus, when the file says so, the first stage's decision
value. A logistic regression on standardised features gives a decision value
``v = ((x - mean) / scale) @ coef + intercept``; a box is kept when ``v > threshold``.

It is trained on pictures of cameras the shipped data holds only teacher labels for
(:mod:`fastdet.train.verifier`, ``python -m tools.scripts.verifier_model``): the first stage's
boxes on every teacher-labelled frame, a box that matches a teacher box (IoU >= 0.5) a
positive, one that overlaps none (IoU < 0.3) and no ignore region a negative. Its ``threshold``
is chosen on cameras held out of the fit: the largest at which the verifier keeps
``keep_fraction`` of the first stage's true boxes there (the cascade's rule: a later stage
must not cost the earlier ones more than a set share of what they found).

File format (``.npz``, read with ``allow_pickle=False``; written atomically)

===============  ============================  =========================================
array            shape, dtype                  meaning
===============  ============================  =========================================
``coef``         ``(F,) float64``              logistic weights on standardised features
``intercept``    ``(1,) float64``              bias
``mean``         ``(F,) float64``              feature means (training set)
``scale``        ``(F,) float64``              feature standard deviations (> 0)
``metadata``     ``(n,) uint8``                UTF-8 JSON: format version, FeatureConfig,
                                               contexts, score_input, threshold, training
===============  ============================  =========================================

``F = len(contexts) * feature_config.n_features + score_input``.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._version import __version__
from ..config import FeatureConfig
from ..config.models import VERIFIER_MODEL_PATH
from ..errors import ModelError
from ..model import read_npz, write_npz
from .regressor import KERNELS, REFINE_FEATURES, box_features

__all__ = ["FORMAT_VERSION", "KERNELS", "VERIFIER_CONTEXTS", "VERIFIER_FEATURES", "BoxVerifier", "load_verifier",
           "verifier_inputs"]

FORMAT_VERSION = 1
_ARRAYS = ("coef", "intercept", "mean", "scale", "metadata")

#: the verifier's appearance features: the box regressor's (luma HOG, 8x8 colour thumbnail) ...
VERIFIER_FEATURES = REFINE_FEATURES
#: ... of the box and of its surroundings (1.5x its width and height)
VERIFIER_CONTEXTS = (1.0, 1.5)


def verifier_inputs(frame: np.ndarray, boxes: np.ndarray, scores: np.ndarray | None,
                    config: FeatureConfig = VERIFIER_FEATURES,
                    contexts: tuple[float, ...] = VERIFIER_CONTEXTS) -> np.ndarray:
    """``(N, len(contexts) * config.n_features [+ 1]) float64``: the appearance features of
    ``boxes (N, 4)`` x1, y1, x2, y2 px in ``frame (H, W, 3) uint8 BGR``
    (:func:`~fastdet.detect.regressor.box_features`), then, when ``scores (N,)`` (the first
    stage's decision values) are given, those as the last column."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    x = box_features(frame, b, config, contexts)
    if scores is None:
        return x
    s = np.asarray(scores, np.float64).reshape(-1)
    if len(s) != len(b):
        raise ValueError(f"{len(s)} scores for {len(b)} boxes")
    return np.concatenate([x, s[:, None]], axis=1)


@dataclass(frozen=True, eq=False)
class BoxVerifier:
    """A linear box verifier (module docstring).

    config: the features of each context crop; contexts: the context factors (> 0);
    score_input: the first stage's decision value is the last input; coef, mean, scale
    ``(F,) float64``, intercept: float; threshold: a box is kept when its decision value
    exceeds it; metadata: what training recorded.
    """

    config: FeatureConfig
    contexts: tuple[float, ...]
    score_input: bool
    coef: np.ndarray
    intercept: float
    mean: np.ndarray
    scale: np.ndarray
    threshold: float
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        ctx = tuple(float(c) for c in self.contexts)
        if not ctx or any(not (math.isfinite(c) and 0 < c <= 4) for c in ctx):
            raise ModelError(f"box verifier: contexts must be numbers in (0, 4], got {self.contexts!r}")
        object.__setattr__(self, "contexts", ctx)
        n = len(ctx) * self.config.n_features + int(bool(self.score_input))
        arrays = {}
        for name in ("coef", "mean", "scale"):
            a = np.asarray(getattr(self, name), np.float64)
            if a.shape != (n,):
                raise ModelError(f"box verifier: {name} must have shape ({n},) for its features, got {a.shape}")
            if not np.isfinite(a).all():
                raise ModelError(f"box verifier: {name} holds a value that is not a finite number")
            arrays[name] = np.ascontiguousarray(a)
        if not (arrays["scale"] > 0).all():
            raise ModelError("box verifier: every scale must be positive")
        for name in ("intercept", "threshold"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not math.isfinite(float(v)):
                raise ModelError(f"box verifier: {name} must be a finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        for name, a in arrays.items():
            object.__setattr__(self, name, a)
        object.__setattr__(self, "score_input", bool(self.score_input))

    @property
    def n_features(self) -> int:
        return len(self.coef)

    def features(self, frame: np.ndarray, boxes: np.ndarray, scores: np.ndarray | None = None) -> np.ndarray:
        """``(N, F) float64`` inputs of ``boxes (N, 4)`` x1, y1, x2, y2 px in ``frame (H, W, 3)
        uint8 BGR``; ``scores (N,)``: the first stage's decision values (needed when
        :attr:`score_input`)."""
        if self.score_input and scores is None:
            raise ValueError("this box verifier takes the first stage's decision values: give scores")
        return verifier_inputs(frame, boxes, scores if self.score_input else None, self.config, self.contexts)

    def decision_function(self, frame: np.ndarray, boxes: np.ndarray, scores: np.ndarray | None = None) -> np.ndarray:
        """``(N,) float64`` decision values of ``boxes`` (:meth:`features`)."""
        x = self.features(frame, boxes, scores)
        if len(x) == 0:
            return np.zeros(0)
        return ((x - self.mean) / self.scale) @ self.coef + self.intercept

    def save(self, path: str | os.PathLike) -> Path:
        """Write the file (module docstring), atomically."""
        meta = {**self.metadata, "format_version": FORMAT_VERSION, "fastdet_version": __version__,
                "feature_config": self.config.to_dict(), "contexts": list(self.contexts),
                "score_input": self.score_input, "threshold": self.threshold}
        return write_npz(path, {"coef": self.coef, "intercept": np.array([self.intercept]), "mean": self.mean,
                                "scale": self.scale}, meta)


def load_verifier(path: str | os.PathLike | None = None) -> BoxVerifier:
    """Load a box verifier (``None``: the bundled :data:`~fastdet.config.models.VERIFIER_MODEL_PATH`).
    Raises :class:`~fastdet.errors.ModelError` naming the problem for a file that is not one."""
    path = Path(path) if path is not None else VERIFIER_MODEL_PATH
    arrays, meta = read_npz(path, _ARRAYS, "box verifier", FORMAT_VERSION)
    try:
        config = FeatureConfig.from_dict(meta["feature_config"])
        contexts = tuple(meta["contexts"])
        score_input, threshold = meta["score_input"], meta["threshold"]
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"box verifier {path}: bad metadata ({exc})") from None
    if not isinstance(score_input, bool) or not all(isinstance(c, (int, float)) for c in contexts):
        raise ModelError(f"box verifier {path}: bad metadata (score_input, contexts)")
    intercept = np.asarray(arrays["intercept"], np.float64).reshape(-1)
    if intercept.shape != (1,):
        raise ModelError(f"box verifier {path}: intercept must hold one number")
    extra = {k: v for k, v in meta.items() if k not in ("feature_config", "contexts", "score_input", "threshold")}
    return BoxVerifier(config, contexts, score_input, arrays["coef"], float(intercept[0]), arrays["mean"],
                       arrays["scale"], threshold, extra)

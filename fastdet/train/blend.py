"""Linear window classifiers combined into one, and one moved along its decision axis: ways to
use a model trained on more cameras without changing what the detector computes.

Every main model is ``score(x) = w . x + b`` on the raw feature vector once its scaler is folded
in (:meth:`fastdet.model.Model.folded`). So

- :func:`blend` of models with the same features is again one such model: the weighted mean of
  their folded weights and biases (a mixture ``m`` of two models scores ``(1 - m) s_a + m s_b``
  on every window), as cheap to search as either;
- :func:`offset` subtracts a constant from the decision value: every threshold the pipeline
  applies to a main-model window (the search's ``p > 0.5``, the slack rows' stricter one, the
  heat map's score range) moves up by that constant in decision units, with no setting changed;
- :func:`rate_offset` finds the constant at which a model lets through as many of some windows
  (e.g. the false windows of annotated frames, :func:`fastdet.train.windows.frame_windows`) as
  a reference model does at its own threshold;
- :func:`side_offset` moves a model's side-view component alone (or drops it).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..model import Model


def blend(models: Sequence[Model], weights: Sequence[float], metadata: dict[str, Any] | None = None) -> Model:
    """One model scoring ``sum_i weights[i] * models[i].score(x)`` (weights normalised to sum to 1,
    each >= 0): folded weights and biases averaged, stored with ``mean`` 0 and ``scale`` 1.

    All models must have one feature configuration and classifier; ``metadata`` is the new
    model's (default: the parts' ``training`` metadata and the weights)."""
    if not models or len(models) != len(weights):
        raise ValueError(f"blend: {len(models)} models and {len(weights)} weights")
    wts = np.asarray(weights, np.float64)
    if not np.all(np.isfinite(wts)) or np.any(wts < 0) or wts.sum() <= 0:
        raise ValueError(f"blend: weights must be finite, >= 0 and not all 0, got {list(weights)}")
    wts = wts / wts.sum()
    cfg, kind = models[0].config, models[0].classifier
    for m in models[1:]:
        if m.config != cfg or m.classifier != kind:
            raise ValueError(f"blend: models of other features or classifiers ({m.config}, {m.classifier} "
                             f"against {cfg}, {kind})")
    w = np.zeros(cfg.n_features)
    b = 0.0
    for m, f in zip(models, wts):
        mw, mb = m.folded()
        w += f * mw
        b += f * mb
    meta = metadata if metadata is not None else {
        "blend": {"weights": [float(v) for v in wts], "parts": [m.metadata.get("training", {}) for m in models]}}
    return Model(config=cfg, coef=w, intercept=b, mean=np.zeros(cfg.n_features), scale=np.ones(cfg.n_features),
                 classifier=kind, metadata=dict(meta))


def offset(model: Model, delta: float, metadata: dict[str, Any] | None = None) -> Model:
    """``model`` with ``delta`` subtracted from every decision value (its intercept lowered by
    ``delta``): the new model's windows above a threshold ``t`` are the old model's above
    ``t + delta``. ``metadata`` is added to the model's; ``offset`` there sums the deltas."""
    if not np.isfinite(delta):
        raise ValueError(f"offset: delta must be finite, got {delta!r}")
    meta = dict(model.metadata)
    meta.update(metadata or {})
    meta["offset"] = float(meta.get("offset", 0.0)) + float(delta)
    return Model(config=model.config, coef=model.coef, intercept=model.intercept - float(delta), mean=model.mean,
                 scale=model.scale, classifier=model.classifier, metadata=meta, regressor=model.regressor,
                 side=model.side)


def side_offset(model: Model, delta: float) -> Model:
    """``model`` with its side-view component (:attr:`Model.side`) moved by ``delta`` as
    :func:`offset` moves a model (+ is stricter); ``delta`` +inf: without the component (no
    window of it is positive). ``ValueError`` when the model carries none."""
    if model.side is None:
        raise ValueError("side_offset: the model carries no side-view component")
    if delta == math.inf:
        return replace(model, side=None)
    return replace(model, side=offset(model.side, delta))


def rate_offset(scores: np.ndarray, reference: np.ndarray, threshold: float = 0.0) -> float:
    """The ``delta`` for :func:`offset` at which a model with decision values ``scores`` (over some
    windows) lets through no more of them than a reference model with decision values
    ``reference`` (over the same or comparable windows, as many) does above ``threshold``:
    ``count(scores > threshold + delta) == count(reference > threshold)`` (fewer only where scores
    tie), ``threshold + delta`` halfway between the two scores either side of that count; negative
    when the model lets through fewer windows than the reference at ``threshold``. ``(N,)``
    arrays of the same length (a rate per window)."""
    s = np.sort(np.asarray(scores, np.float64).ravel())[::-1]
    r = np.asarray(reference, np.float64).ravel()
    if len(s) != len(r) or not len(s):
        raise ValueError(f"rate_offset: {len(s)} scores and {len(r)} reference scores (the same windows, not none)")
    if not (np.all(np.isfinite(s)) and np.all(np.isfinite(r))):
        raise ValueError("rate_offset: scores must be finite")
    k = int((r > threshold).sum())  # windows the reference lets through
    above = s[k - 1] if k > 0 else s[0] + 1.0  # the k-th best score must stay in, the (k+1)-th out
    below = s[k] if k < len(s) else s[-1] - 1.0
    return float((above + below) / 2 - threshold)

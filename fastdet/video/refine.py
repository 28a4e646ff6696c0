"""Learned bounding-box refinement of a stream's boxes: :func:`refine` applies the box
regressor (:mod:`fastdet.detect.regressor`: its features, offsets and file) to a frame's
:class:`~fastdet.detections.Detections`: the offsets are clamped
(:attr:`RefineConfig.max_shift`, :attr:`RefineConfig.max_log_scale`), decoded
(:func:`~fastdet.detect.regressor.decode_offsets`), optionally applied again from the new box
(:attr:`RefineConfig.iterations`), rounded and clipped to the frame; every other column
(scores, ids, part, scale) is kept. A cascade (:attr:`BoxRegressor.n_stages` > 1) takes
step ``i`` with its ``i``-th stage (the last one for the steps after them).
:func:`regressor_for` picks the regressor of a pipeline's model files.
"""
from __future__ import annotations

import os
from dataclasses import replace

import numpy as np

from ..config import RefineConfig
from ..detect.regressor import (  # noqa: F401 - the regressor's names, as this module gave them
    KERNELS,
    REFINE_FEATURES,
    REFINE_MODEL_PATH,
    BoxFeatures,
    BoxRegressor,
    carried_regressor,
    decode_offsets,
    encode_offsets,
    load_regressor,
)
from ..detections import Detections
from ..model import Model, load_model


def regressor_for(model: Model | str | os.PathLike[str] | None,
                  refine_model: str | os.PathLike[str] | None, *,
                  name: str | os.PathLike[str] | None = None) -> BoxRegressor:
    """The box regressor a pipeline with main model ``model`` (a loaded :class:`~fastdet.model.Model`
    or its file) and regressor file ``refine_model`` (:class:`~fastdet.config.PipelineConfig`'s,
    ``None``: not given) refines with: ``refine_model`` when given; else the one ``model``
    carries (a model ``fastdet adapt`` made for its camera); else the bundled one. ``name``: what
    an error about a carried regressor calls a loaded ``model`` (its file)."""
    carried = carried_regressor_for(model, refine_model, name=name)
    return carried if carried is not None else load_regressor(refine_model)


def carried_regressor_for(model: Model | str | os.PathLike[str] | None,
                          refine_model: str | os.PathLike[str] | None, *,
                          name: str | os.PathLike[str] | None = None) -> BoxRegressor | None:
    """The regressor ``model`` carries when :func:`regressor_for` picks it (no ``refine_model``
    named, and the model carries one); else ``None`` (the named or the bundled file is used).
    The one place that says a named file wins over a carried regressor."""
    if refine_model is not None or model is None:
        return None
    loaded = model if isinstance(model, Model) else load_model(model)
    if name is None:
        name = "the model" if isinstance(model, Model) else model
    return carried_regressor(loaded, str(name))


# ---------------------------------------------------------------------------------------- refinement


def refine_boxes(frame: np.ndarray, boxes: np.ndarray, regressor: BoxRegressor,
                 config: RefineConfig = RefineConfig()) -> np.ndarray:
    """Refined ``(N, 4) float64`` boxes (not rounded or clipped) of ``boxes (N, 4)`` x1, y1,
    x2, y2 in ``frame (H, W, 3) uint8 BGR``; boxes below ``config.min_size`` stay as they are.
    ``regressor``: one regressor or a cascade (module docstring)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4).copy()
    ok = ((b[:, 2] - b[:, 0]) >= config.min_size) & ((b[:, 3] - b[:, 1]) >= config.min_size)
    if not ok.any():
        return b
    cur = b[ok]
    lim = np.array([config.max_shift, config.max_shift, config.max_log_scale, config.max_log_scale])
    for i in range(config.iterations):
        t = np.clip(regressor.predict(frame, cur, stage=i), -lim, lim)
        cur = decode_offsets(cur, t)
    b[ok] = cur
    return b


def refine(frame: np.ndarray, dets: Detections, regressor: BoxRegressor,
           config: RefineConfig = RefineConfig()) -> Detections:
    """``dets`` of ``frame (H, W, 3) uint8 BGR`` with their boxes refined (:func:`refine_boxes`),
    rounded to whole pixels and clipped to the frame; the other columns as they were. Boxes
    of parts not in ``config.parts`` are not touched."""
    frame = np.asarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.dtype} {frame.shape}")
    if len(dets) == 0:
        return dets
    sel = np.ones(len(dets), bool)
    if config.parts is not None:
        part = dets.part if dets.part is not None else np.zeros(len(dets), np.int8)
        sel = np.isin(part, config.parts)
        if not sel.any():
            return dets
    new = dets.boxes.astype(np.float64)
    new[sel] = refine_boxes(frame, new[sel], regressor, config)
    H, W = frame.shape[:2]
    r = np.rint(new)
    moved = np.any(r != dets.boxes, axis=1)  # a box that did not move is not clipped either
    r[:, [0, 2]] = np.where(moved[:, None], np.clip(r[:, [0, 2]], 0, W), r[:, [0, 2]])
    r[:, [1, 3]] = np.where(moved[:, None], np.clip(r[:, [1, 3]], 0, H), r[:, [1, 3]])
    # a box clipped to nothing keeps its old coordinates
    bad = (r[:, 2] <= r[:, 0]) | (r[:, 3] <= r[:, 1])
    r[bad] = dets.boxes[bad]
    return replace(dets, boxes=r.astype(np.int32))

"""Vehicles in one picture, with no video to place the search from: :class:`PictureDetector`
and :func:`detect_picture`.

The whole picture is searched at every scale (:class:`~fastdet.config.PictureSearch`: window
sizes from 1/32 of the width up to the picture's height), and the positive windows become
one box per vehicle by non-maximum suppression. Then the video's learned box regressor
(:mod:`fastdet.video.refine`, ``PictureSearch.refine``) moves each box onto its vehicle: a square
window on a car wider than tall reaches IoU 0.5 with it only when the car is at most twice as wide
as tall, and the regressor fits the box to the car; the box verifier
(:mod:`fastdet.detect.verifier`, ``PictureSearch.verify``) keeps the boxes it is sure of.
``python -m fastdet image`` runs exactly this, so the command and the call give the same boxes.
"""
from __future__ import annotations

import os
from collections import OrderedDict
from dataclasses import replace
from typing import Any

import numpy as np

from ..config import PictureSearch
from ..detect import Detector
from ..detect.verifier import BoxVerifier, load_verifier
from ..detections import Detections
from ..model import Model, load_model
from .plausible import duplicates
from .refine import KERNELS as REFINE_KERNELS
from .refine import BoxRegressor, refine, regressor_for

#: pictures sizes whose :class:`fastdet.Detector` a :class:`PictureDetector` keeps
_CACHED_SHAPES = 8


def _decision(scores: np.ndarray, score_kind: str) -> np.ndarray:
    """Decision values of ``scores`` (probabilities of a logistic model -> their logit)."""
    s = np.asarray(scores, np.float64)
    if score_kind != "probability":
        return s
    p = np.clip(s, 1e-12, 1 - 1e-12)
    return np.log(p / (1 - p))


class PictureDetector:
    """Finds the vehicles of single pictures of any size (module docstring).

    model: a :class:`~fastdet.model.Model`, a model file, or ``None`` for the bundled model.
    config: the :class:`~fastdet.config.PictureSearch` (default ``PictureSearch()``).
    refine_model: the box regressor (a :class:`~fastdet.video.refine.BoxRegressor` or its file;
        ``None``: the one the model carries (``fastdet adapt``'s), else the bundled one), used
        when ``config.refine`` is set.
    verifier: the box verifier (a :class:`~fastdet.detect.verifier.BoxVerifier` or its file;
        ``None``: the bundled one), used when ``config.verify`` is set.

    :meth:`detect` returns one box per vehicle: :meth:`windows`, the positive windows,
    :meth:`boxes_from_windows`, one box per vehicle as found (NMS), then :meth:`second_stage`
    (:meth:`refine`, then :meth:`verify`). One :class:`fastdet.Detector` is kept per picture
    size (the last few sizes).
    """

    def __init__(self, model: Model | str | os.PathLike[str] | None = None,
                 config: PictureSearch | None = None,
                 refine_model: BoxRegressor | str | os.PathLike[str] | None = None,
                 verifier: BoxVerifier | str | os.PathLike[str] | None = None) -> None:
        self.model = model if isinstance(model, Model) else load_model(model)
        if self.model.side is not None:
            # a camera's side-view component is chosen for its video's window boxes; the picture
            # search, its verifier and regressor are fitted on square windows: it is not searched here
            self.model = replace(self.model, side=None)
        self.config = config if config is not None else PictureSearch()
        if not isinstance(self.config, PictureSearch):
            raise TypeError(f"config must be a PictureSearch, got {type(self.config).__name__}")
        self.regressor: BoxRegressor | None = None
        if self.config.refine is not None:
            self.regressor = (refine_model if isinstance(refine_model, BoxRegressor)
                              else regressor_for(self.model, refine_model))
        self.verifier: BoxVerifier | None = None
        if self.config.verify:
            self.verifier = verifier if isinstance(verifier, BoxVerifier) else load_verifier(verifier)
        self.score_kind = self.model.score_kind
        self._detectors: OrderedDict[tuple[int, int], Detector] = OrderedDict()

    @property
    def kernels(self) -> tuple[Any, ...]:
        """Every numba kernel :meth:`detect` runs (to compile them all at once)."""
        second = self.regressor is not None or self.verifier is not None
        return (*Detector.kernels, *(REFINE_KERNELS if second else ()))

    def detector(self, shape: tuple[int, ...]) -> Detector:
        """The :class:`fastdet.Detector` that searches pictures of ``shape = (H, W[, C])``
        (:meth:`PictureSearch.search <fastdet.config.PictureSearch.search>`). ``ValueError``
        when the picture is smaller than the smallest window."""
        key = (int(shape[0]), int(shape[1]))
        det = self._detectors.get(key)
        if det is None:
            cfg = self.model.config
            det = Detector(self.model, self.config.search(key, cfg.win_w, cfg.pixels_per_cell))
            self._detectors[key] = det
            while len(self._detectors) > _CACHED_SHAPES:
                self._detectors.popitem(last=False)[1].close()
        else:
            self._detectors.move_to_end(key)
        return det

    def windows(self, image: np.ndarray, rgb: bool = False) -> Detections:
        """The positive windows of ``image`` (``(H, W, 3) uint8``, BGR or RGB with ``rgb``):
        boxes ``(N, 4) int32`` px, scores in the model's kind (probability or decision value)."""
        return self.detector(np.shape(image)).detect(image, rgb=rgb)

    def boxes_from_windows(self, windows: Detections) -> Detections:
        """One box per vehicle from a picture's positive ``windows``: those above
        ``config.nms_min_score`` after non-maximum suppression at ``config.nms_iou``, each scored
        by its decision value."""
        dec = _decision(windows.scores, self.score_kind)
        strong = windows[dec > self.config.nms_min_score]
        dec = dec[dec > self.config.nms_min_score]
        keep = duplicates(strong.boxes, dec, self.config.nms_iou)
        return Detections(strong.boxes[keep].astype(np.int32), dec[keep].astype(np.float32))

    def refine(self, image: np.ndarray, boxes: Detections, rgb: bool = False) -> Detections:
        """``boxes`` of ``image`` (``(H, W, 3) uint8``, BGR or RGB with ``rgb``) moved onto
        their vehicles by the box regressor (``config.refine``; unchanged when it is ``None``);
        scores as they were."""
        if self.regressor is None or self.config.refine is None or len(boxes) == 0:
            return boxes
        bgr = np.ascontiguousarray(np.asarray(image)[..., ::-1]) if rgb else np.asarray(image)
        return refine(bgr, boxes, self.regressor, self.config.refine)

    def verify(self, image: np.ndarray, boxes: Detections, rgb: bool = False) -> Detections:
        """The ``boxes`` of ``image`` (``(H, W, 3) uint8``, BGR or RGB with ``rgb``; scores: the
        windows' decision values) that the verifier keeps, scored by its decision value
        (unchanged when ``config.verify`` is off)."""
        if self.verifier is None or len(boxes) == 0:
            return boxes
        bgr = np.ascontiguousarray(np.asarray(image)[..., ::-1]) if rgb else np.asarray(image)
        v = self.verifier.decision_function(bgr, boxes.boxes, boxes.scores)
        keep = v > self.verifier.threshold
        return Detections(boxes.boxes[keep], v[keep].astype(np.float32))

    def second_stage(self, image: np.ndarray, found: Detections, rgb: bool = False) -> Detections:
        """The boxes :meth:`boxes_from_windows` ``found`` in ``image``, refined (:meth:`refine`)
        and verified (:meth:`verify`)."""
        if rgb and (self.regressor is not None or self.verifier is not None) and len(found):
            image, rgb = np.ascontiguousarray(np.asarray(image)[..., ::-1]), False  # converted once for both
        return self.verify(image, self.refine(image, found, rgb), rgb)

    def detect(self, image: np.ndarray, rgb: bool = False) -> Detections:
        """One box per vehicle in ``image`` (``(H, W, 3) uint8``, BGR or RGB with ``rgb``):
        :class:`~fastdet.detections.Detections` with ``boxes (N, 4) int32`` x1, y1, x2, y2
        (exclusive) px and ``scores (N,) float32`` (the window's decision value; the verifier's
        decision value when ``config.verify``)."""
        found = self.boxes_from_windows(self.windows(image, rgb))
        return self.second_stage(image, found, rgb)

    def warmup(self) -> None:
        """Compile (or load) the kernels and run them once on a small picture."""
        Detector(self.model, self.config.search((128, 128))).warmup()
        if self.regressor is not None or self.verifier is not None:
            self.second_stage(np.zeros((64, 64, 3), np.uint8), Detections(np.array([[8, 8, 56, 56]], np.int32),
                                                                          np.ones(1, np.float32)))

    def close(self) -> None:
        """Stop the detectors' band threads."""
        for det in self._detectors.values():
            det.close()
        self._detectors.clear()


_DEFAULT: dict[Any, PictureDetector] = {}


def detect_picture(image_bgr: np.ndarray, model: Model | str | os.PathLike[str] | None = None,
                   config: PictureSearch | None = None) -> Detections:
    """The vehicles of one picture: ``image_bgr (H, W, 3) uint8`` (OpenCV's BGR order), the
    bundled model or ``model`` (a :class:`~fastdet.model.Model` or model file), the default
    :class:`~fastdet.config.PictureSearch` or ``config``. Returns
    :class:`~fastdet.detections.Detections` (``boxes (N, 4) int32`` x1, y1, x2, y2 px,
    ``scores (N,) float32``): the same boxes as ``python -m fastdet image``. The detector of a
    model given by path or the bundled one is kept between calls (pass a
    :class:`PictureDetector` around yourself for other models)."""
    key = (None if model is None else os.fspath(model) if not isinstance(model, Model) else id(model), config)
    det = _DEFAULT.get(key) if not isinstance(model, Model) else None
    if det is None:
        det = PictureDetector(model, config)
        if not isinstance(model, Model):
            _DEFAULT.clear()  # keep one: a model is megabytes
            _DEFAULT[key] = det
    return det.detect(np.asarray(image_bgr))

"""Stand-ins for :class:`fastdet.Detector`: objects that follow the
:class:`fastdet.video.WindowDetector` protocol (``score_kind``, ``oncoming_model``, ``warmup()``,
``geometries()``, ``detect()``), so the video pipeline, the CLI commands and the tools can run
without a trained model or with windows recorded once.

- :class:`BrightBoxDetector`: five windows around the bounding box of every pixel brighter
  than 200 (one object per frame), scales 1..3; counts its calls.
- :class:`BlobsDetector`: five windows around each connected bright region.
- :class:`SquareDetector`: three windows around the bright pixels, none of the optional
  abilities (no horizon, no column search, no kernels).
- :class:`FixedDetector`: the same windows on every frame (a full search: no motion gate).
- :class:`ReplayDetector`: windows recorded earlier, one frame per call (``tools/``).
- :class:`RecordingDetector`: passes through to a real detector and keeps every result, or
  replays a recorded list (``tools/``).
- :func:`model_carrying_side`: the bundled model with a random side-view component.

Used by ``tests/`` and ``tools/`` (run from the repository root: ``tests`` is importable).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy import ndimage

from fastdet.detections import Detections

# the five windows every bright-region fake puts around a region: the box itself and shifted 4 px
SHIFTS = ((0, 0), (4, 0), (-4, 0), (0, 4), (0, -4))
SCALES = (1.0, 1.5, 2.0, 2.5, 3.0)


def _bright(frame: np.ndarray) -> np.ndarray:
    return frame.max(axis=2) > 200


class _NoSearch:
    """What the fakes without search bands share."""

    score_kind = "decision"
    oncoming_model: Any = None

    def warmup(self) -> None:
        pass

    def geometries(self, frame_shape, part=0):
        return []


class BrightBoxDetector(_NoSearch):
    """Five windows around the bounding box of the pixels brighter than 200 (the box itself and
    shifted by 4 px), scales 1..3, score 1. ``on_frame(calls)`` runs before each frame."""

    def __init__(self, on_frame: Callable[[int], None] | None = None):
        self.calls = 0
        self.rgb_args: list[bool] = []
        self.warmed = False
        self.on_frame = on_frame

    def warmup(self) -> None:
        self.warmed = True

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands=None, stats=None) -> Detections:
        self.calls += 1
        self.rgb_args.append(rgb)
        if self.on_frame is not None:
            self.on_frame(self.calls)
        if stats is not None:
            stats.timings.update({"resize_colour": 1e-4, "hog": 2e-4, "score": 3e-4})
        ys, xs = np.nonzero(_bright(frame))
        if len(xs) == 0:
            return Detections.empty()
        x1, y1, x2, y2 = xs.min(), ys.min(), xs.max() + 1, ys.max() + 1
        boxes = np.array([[x1 + dx, y1 + dy, x2 + dx, y2 + dy] for dx, dy in SHIFTS], np.int32)
        return Detections(boxes, np.full(5, 1.0, np.float32), scale=np.array(SCALES, np.float32))


class BlobsDetector(_NoSearch):
    """Five windows (the region's box and shifted 4 px) around each connected region of pixels
    brighter than 200, in raster order of the regions, each scored ``score``; with
    ``scales=True`` the five windows have scales 1..3."""

    def __init__(self, score: float = 1.0, scales: bool = False):
        self.score, self.scales = score, scales

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands=None, stats=None) -> Detections:
        labels, _ = ndimage.label(_bright(frame))
        boxes = []
        for sl in ndimage.find_objects(labels):
            y1, y2, x1, x2 = sl[0].start, sl[0].stop, sl[1].start, sl[1].stop
            boxes += [[x1 + dx, y1 + dy, x2 + dx, y2 + dy] for dx, dy in SHIFTS]
        if stats is not None:
            stats.timings.update({"resize_colour": 0.0, "hog": 0.0, "score": 0.0})
        if not boxes:
            return Detections.empty()
        scale = np.tile(np.array(SCALES, np.float32), len(boxes) // 5) if self.scales else None
        return Detections(np.array(boxes, np.int32), np.full(len(boxes), self.score, np.float32), scale=scale)


class SquareDetector(_NoSearch):
    """A WindowDetector without optional abilities: three windows (the box of the pixels
    brighter than 200, and shifted 4 px right and down), score 2, scale 1."""

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands=None, stats=None) -> Detections:
        if stats is not None:
            stats.timings.update({"resize_colour": 0.0, "hog": 0.0, "score": 0.0})
        ys, xs = np.nonzero(_bright(frame))
        if len(xs) == 0:
            return Detections.empty()
        b = [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1]
        boxes = np.array([b, [b[0] + 4, b[1], b[2] + 4, b[3]], [b[0], b[1] + 4, b[2], b[3] + 4]], np.int32)
        return Detections(boxes, np.full(3, 2.0, np.float32), scale=np.ones(3, np.float32))


class FixedDetector(_NoSearch):
    """The same windows ``dets`` on every frame. It has no search bands, so it stands only for
    a full search: asking for its bands (the motion gate does) or for part of the wide search
    is a test error. ``oncoming_model``: not None makes VideoDetector route the wide windows
    (``part`` ONCOMING_PART) to the wide heat map."""

    def __init__(self, dets: Detections, oncoming_model: Any = None):
        self.dets, self.oncoming_model = dets, oncoming_model

    def geometries(self, frame_shape, part=0):
        raise AssertionError("FixedDetector has no search bands (turn the motion gate off)")

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands=None, stats=None) -> Detections:
        assert oncoming_bands is None, "FixedDetector stands for the full search only"
        return self.dets


class ReplayDetector:
    """Windows recorded earlier, ``frames[i]`` on the i-th :meth:`detect` call (``frame``
    counts the calls). ``like`` (the detector that recorded them) gives ``score_kind``,
    ``oncoming_model`` and the search bands. When VideoDetector asks for no ``oncoming_bands`` (nothing
    moved, or the first frame), the wide windows are left out, as the real detector leaves out
    the wide search."""

    def __init__(self, frames: Sequence[Detections], like: Any):
        self.frames, self.like = frames, like
        self.score_kind = like.score_kind
        self.oncoming_model = like.oncoming_model
        self.frame = 0

    def warmup(self) -> None:
        pass

    def geometries(self, frame_shape, part=0):
        return self.like.geometries(frame_shape, part)

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands=None, stats=None) -> Detections:
        d = self.frames[self.frame]
        self.frame += 1
        if oncoming_bands is not None and len(oncoming_bands) == 0:
            d = d[~d.is_oncoming]
        return d


class RecordingDetector:
    """Passes every call through to ``det`` (a real detector, whose horizon it follows) and
    keeps every :meth:`detect` result in ``record``; with ``replay`` (such a record) returns
    ``replay[i]`` on the i-th call instead of detecting."""

    def __init__(self, det: Any, replay: list[Detections] | None = None):
        self.det, self.replay = det, replay
        self.score_kind, self.oncoming_model = det.score_kind, det.oncoming_model
        self.record: list[Detections] = []

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands=None, stats=None) -> Detections:
        if self.replay is not None:
            d = self.replay[len(self.record)]
        else:
            d = self.det.detect(frame, rgb=rgb, oncoming_bands=oncoming_bands, stats=stats)
        self.record.append(d)
        return d

    def warmup(self) -> None:
        if self.replay is None:
            self.det.warmup()

    def geometries(self, frame_shape, part=0):
        return self.det.geometries(frame_shape, part)

    @property
    def horizon(self):
        return self.det.horizon

    def set_horizon(self, horizon) -> None:
        self.det.set_horizon(horizon)


def model_carrying_side(frame: np.ndarray, positive: float = 0.005) -> Any:
    """The bundled model carrying a random side-view component (64x32 windows of its features,
    :attr:`fastdet.model.Model.side`), standardised on windows of ``frame`` and letting about
    ``positive`` of them through: a component that fires somewhere, without a fit."""
    from dataclasses import replace

    import cv2

    from fastdet.features import extract_features
    from fastdet.model import Model, load_model
    from fastdet.train.side import side_config

    main = load_model()
    cfg = side_config(main.config)
    rng = np.random.default_rng(0)
    h, w = frame.shape[:2]
    ys, xs, hs = rng.integers(h // 2, h - 40, 300), rng.integers(0, w - 80, 300), rng.choice([16, 24, 32], 300)
    crops = np.stack([cv2.resize(frame[y:y + s, x:x + 2 * s], (cfg.win_w, cfg.win_h)) for y, x, s in zip(ys, xs, hs)])
    x = extract_features(crops, cfg)
    mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-3
    coef = rng.normal(size=cfg.n_features) * 3 / np.sqrt(cfg.n_features)
    dec = ((x - mean) / scale) @ coef
    side = Model(cfg, coef, -float(np.quantile(dec, 1 - positive)), mean, scale, classifier=main.classifier)
    return replace(main, side=side)

"""The box regressor's model: a linear regressor from a box's appearance to the offsets that
move it onto the vehicle (as DPM's and R-CNN's box regression) -- its features, its offsets,
its file. Fitting (:mod:`fastdet.train.refine`) and refining a stream's boxes
(:mod:`fastdet.video.refine`) both import it from here.

A box ``x1, y1, x2, y2`` (frame pixels) with centre ``cx, cy`` and size ``w, h`` and the
vehicle's box with ``cx', cy', w', h'`` differ by the offsets (:func:`encode_offsets`)::

    tx = (cx' - cx) / w    ty = (cy' - cy) / h    tw = log(w' / w)    th = log(h' / h)

:class:`BoxRegressor` predicts ``(tx, ty, tw, th)`` from features of the box's region: for
each context factor ``c`` of :attr:`RefineConfig.contexts`, the region of ``c x`` the box's
width and height about its centre (parts outside the frame replicate the border pixels),
resized to the feature window (64x64) and described by :func:`fastdet.features.extract_features`
with the regressor's :class:`~fastdet.config.FeatureConfig`. A context above 1 lets it see
where the vehicle continues beyond the box. The prediction is a ridge regression on
standardised features: ``t = ((x - mean) / scale) @ coef.T + intercept``.

A regressor may be a *cascade* of ``S`` stages (:meth:`BoxRegressor.stack`, fitted by
:func:`fastdet.train.refine.fit_cascade`): the same features, one set of arrays per stage;
refinement step ``i`` uses stage ``i`` (the last stage for the steps after them). A
one-stage regressor's file holds the arrays as below; a cascade's hold them with a leading
stage axis (``coef (S, 4, F)``, ``intercept (S, 4)``, ``mean (S, F)``, ``scale (S, F)``).

File format (``.npz``, read with ``allow_pickle=False``; written atomically)

===============  ============================  =========================================
array            shape, dtype                  meaning
===============  ============================  =========================================
``coef``         ``(4, F) float64``            ridge weights on standardised features
``intercept``    ``(4,) float64``              offsets of the mean feature vector
``mean``         ``(F,) float64``              feature means (training set)
``scale``        ``(F,) float64``              feature standard deviations (> 0)
``metadata``     ``(n,) uint8``                UTF-8 JSON: format version, FeatureConfig,
                                               contexts, training data and figures
===============  ============================  =========================================

``F = len(contexts) * feature_config.n_features``. :mod:`fastdet.train.refine` fits the arrays
(given a :class:`BoxFeatures`), :meth:`BoxRegressor.from_fit` makes the regressor of them.

A file whose metadata lists ``size_inputs`` (the box's size among the inputs: an option that
no clip supported, deleted; docs/accuracy.md, "Deleted stages") is refused with one line.
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numba
import numpy as np

from .._numba import longest_first, split_range
from .._version import __version__
from ..config import FeatureConfig
from ..config.models import REFINE_MODEL_PATH
from ..errors import ModelError
from ..features import extract_features
from ..features.window import KERNELS as FEATURE_KERNELS
from ..model import Model, read_npz, write_npz
from ._crop_kernels import area_crops

#: the numba kernels of :func:`box_features` (compiled ahead of time: fastdet._numba.ensure_compiled)
KERNELS = (*FEATURE_KERNELS, area_crops)

FORMAT_VERSION = 1
_ARRAYS = ("coef", "intercept", "mean", "scale", "metadata")
#: the regressor's default features: HOG of the luma channel (9 orientations, 8-px cells) and
#: an 8x8 colour thumbnail, no histogram: 1956 values per context
REFINE_FEATURES = FeatureConfig(color_space="YCrCb", hog_channels=(0,), orientations=9, pixels_per_cell=8,
                                cells_per_block=2, spatial_size=8, hist_bins=0)


# ---------------------------------------------------------------------------------------- offsets


def encode_offsets(boxes: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Offsets ``(N, 4) float64`` ``(tx, ty, tw, th)`` that take ``boxes (N, 4)`` to
    ``targets (N, 4)`` (both ``x1, y1, x2, y2`` pixels, positive width and height; module
    docstring)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    g = np.asarray(targets, np.float64).reshape(-1, 4)
    w, h = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
    gw, gh = g[:, 2] - g[:, 0], g[:, 3] - g[:, 1]
    if np.any(w <= 0) or np.any(h <= 0) or np.any(gw <= 0) or np.any(gh <= 0):
        raise ValueError("encode_offsets: every box needs a positive width and height")
    return np.stack([(g[:, 0] + 0.5 * gw - b[:, 0] - 0.5 * w) / w, (g[:, 1] + 0.5 * gh - b[:, 1] - 0.5 * h) / h,
                     np.log(gw / w), np.log(gh / h)], axis=1)


def decode_offsets(boxes: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """The boxes ``(N, 4) float64`` that ``offsets (N, 4)`` ``(tx, ty, tw, th)`` make of
    ``boxes (N, 4)`` (``x1, y1, x2, y2`` pixels); the inverse of :func:`encode_offsets`."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    t = np.asarray(offsets, np.float64).reshape(-1, 4)
    w, h = b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]
    cx, cy = b[:, 0] + 0.5 * w + t[:, 0] * w, b[:, 1] + 0.5 * h + t[:, 1] * h
    nw, nh = w * np.exp(t[:, 2]), h * np.exp(t[:, 3])
    return np.stack([cx - 0.5 * nw, cy - 0.5 * nh, cx + 0.5 * nw, cy + 0.5 * nh], axis=1)


# ---------------------------------------------------------------------------------------- features


#: below this many region pixel-channels the crops are made on one thread: waking a second one
#: costs more than it saves on a loaded machine (about 0.7 ms of work; a video frame's few boxes)
_PARALLEL_MIN_SAMPLES = 1_000_000


def _region(H: int, W: int, box: np.ndarray, context: float) -> tuple[int, ...]:
    """The pixels of the region of ``context x`` the ``box``'s (x1, y1, x2, y2) width and
    height about its centre, in a frame of ``H x W``: its rows ``y0 <= y < y1`` and columns
    ``x0 <= x < x1`` (may run past the frame), then the part inside the frame that the region
    repeats at its border, ``ylo, yhi, xlo, xhi`` (inclusive):
    ``(y0, y1, x0, x1, ylo, yhi, xlo, xhi)``."""
    x1, y1, x2, y2 = (float(v) for v in box)
    cx, cy = 0.5 * (x1 + x2), 0.5 * (y1 + y2)
    hw, hh = 0.5 * context * max(x2 - x1, 1.0), 0.5 * context * max(y2 - y1, 1.0)
    a, c = int(math.floor(cx - hw)), int(math.ceil(cx + hw))
    r, d = int(math.floor(cy - hh)), int(math.ceil(cy + hh))
    # stay within one frame of padding either side (a box far outside is junk anyway)
    a, c = max(a, -W), min(max(c, a + 1), 2 * W)
    r, d = max(r, -H), min(max(d, r + 1), 2 * H)
    ia, ic, ir, id_ = max(a, 0), min(c, W), max(r, 0), min(d, H)
    if ic <= ia or id_ <= ir:  # wholly outside: the nearest border pixel
        ia, ic = min(max(ia, 0), W - 1), min(max(ia, 0), W - 1) + 1
        ir, id_ = min(max(ir, 0), H - 1), min(max(ir, 0), H - 1) + 1
    # the part inside the frame padded by what lies outside it (a region wholly outside also
    # spans the border pixel it repeats)
    return min(r, ir), max(d, id_), min(a, ia), max(c, ic), ir, id_ - 1, ia, ic - 1


def _area_scales(src: tuple[int, int], dst: tuple[int, int]) -> tuple[float, float] | None:
    """OpenCV's source pixels per output pixel ``(x, y)`` of an ``INTER_AREA`` resize of
    ``src = (h, w)`` to ``dst = (h, w)`` when it takes its general path (:mod:`._crop_kernels`):
    the region at least ``dst`` in both directions, the scales not both whole numbers (OpenCV's
    test, on its doubles); else ``None``."""
    (sh, sw), (dh, dw) = src, dst
    if sh < dh or sw < dw:
        return None
    sx, sy = 1.0 / (dw / sw), 1.0 / (dh / sh)  # cv::resize: inv_scale = dst / src; hal::resize: 1 / inv_scale
    eps = float(np.finfo(np.float64).eps)
    if abs(sx - round(sx)) < eps and abs(sy - round(sy)) < eps:
        return None  # OpenCV's integer-scale path (resizeAreaFast): left to cv2.resize
    return sx, sy


def _cv2_crop(frame: np.ndarray, g: tuple[int, ...], size: tuple[int, int]) -> np.ndarray:
    """One region of :func:`_region` geometry ``g`` resized to ``size = (h, w)`` by
    ``cv2.resize`` (``INTER_AREA`` shrinking, ``INTER_LINEAR`` else; the border replicated)."""
    y0, y1, x0, x1, ylo, yhi, xlo, xhi = g
    oh, ow = size
    reg = frame[ylo:yhi + 1, xlo:xhi + 1]
    pads = (ylo - y0, y1 - yhi - 1, xlo - x0, x1 - xhi - 1)
    if any(pads):
        reg = cv2.copyMakeBorder(reg, *pads, cv2.BORDER_REPLICATE)
    interp = cv2.INTER_AREA if reg.shape[0] >= oh and reg.shape[1] >= ow else cv2.INTER_LINEAR
    return cv2.resize(reg, (ow, oh), interpolation=interp)


def regions_crops(frame: np.ndarray, boxes: np.ndarray, contexts: tuple[float, ...],
                  size: tuple[int, int]) -> np.ndarray:
    """:func:`region_crops` of every context factor of ``contexts`` at once:
    ``(len(contexts), N, height, width, 3) uint8``. The shrunk regions come from one kernel
    (:func:`._crop_kernels.area_crops`: OpenCV's ``INTER_AREA`` to the bit, straight from the
    frame), spread over Numba's thread count of threads, largest first; the others (enlarged,
    or shrunk by whole numbers) from ``cv2.resize``."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    if not np.isfinite(b).all():
        raise ValueError("boxes must be finite numbers")
    frame = np.ascontiguousarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.dtype} {frame.shape}")
    H, W = frame.shape[:2]
    oh, ow = (int(v) for v in size)
    if oh < 1 or ow < 1:
        raise ValueError(f"size must be positive, got {size!r}")
    n = len(b)
    out = np.empty((len(contexts) * n, oh, ow, 3), np.uint8)
    geo = np.empty((len(out), 8), np.int64)
    scales = np.zeros((len(out), 2), np.float64)
    fast = []
    # box by box in Python: for a video frame's one or two boxes this costs less than the same
    # integer arithmetic in NumPy on tiny arrays (~0.3 ms a call)
    for k, context in enumerate(contexts):
        for i in range(n):
            j = k * n + i
            g = _region(H, W, b[i], float(context))
            geo[j] = g
            sc = _area_scales((g[1] - g[0], g[3] - g[2]), (oh, ow))
            if sc is None:
                out[j] = _cv2_crop(frame, g, (oh, ow))
            else:
                scales[j] = sc
                fast.append(j)
    if fast:
        rows = frame.reshape(H, W * 3)
        rows.flags.writeable = False  # one signature, whatever the caller's array
        cost = (geo[fast, 1] - geo[fast, 0]) * (geo[fast, 3] - geo[fast, 2])
        parts = 1 if 3 * int(cost.sum()) < _PARALLEL_MIN_SAMPLES else max(1, min(numba.get_num_threads(), len(fast)))
        if parts == 1:
            orders = [np.array(fast, np.int64)]
        else:  # largest first, each to the least loaded thread
            orders = [np.array(sorted(fast[t] for t in share), np.int64)
                      for share in longest_first(cost.tolist(), parts)]

        def run(lo: int, hi: int) -> None:
            for p in range(lo, hi):
                area_crops(rows, geo, scales, orders[p], out)

        split_range(run, parts, parts)
    return out.reshape(len(contexts), n, oh, ow, 3)


def region_crops(frame: np.ndarray, boxes: np.ndarray, context: float, size: tuple[int, int]) -> np.ndarray:
    """The regions of ``context x`` each box's width and height about its centre, resized to
    ``size = (height, width)``: ``(N, height, width, 3) uint8`` (same channel order as
    ``frame (H, W, 3) uint8``). Pixels outside the frame replicate its border; shrinking uses
    ``cv2.INTER_AREA``, enlarging ``cv2.INTER_LINEAR`` (the same pixels as ``cv2.resize`` of
    the padded region: ``tests/reference.py``, :func:`regions_crops`)."""
    return regions_crops(frame, boxes, (float(context),), size)[0]


def box_features(frame: np.ndarray, boxes: np.ndarray, config: FeatureConfig,
                 contexts: tuple[float, ...]) -> np.ndarray:
    """Features of ``boxes (N, 4)`` in ``frame (H, W, 3) uint8 BGR``: for each context factor,
    :func:`extract_features` of :func:`region_crops`, concatenated:
    ``(N, len(contexts) * config.n_features) float64``."""
    n = len(np.asarray(boxes).reshape(-1, 4))
    if n == 0:
        return np.zeros((0, len(contexts) * config.n_features), np.float64)
    crops = regions_crops(frame, boxes, contexts, (config.win_h, config.win_w))
    # every context's crops described at once (each crop's features are its own)
    x = extract_features(crops.reshape((-1,) + crops.shape[2:]), config)
    return np.concatenate([x[k * n: (k + 1) * n] for k in range(len(contexts))], axis=1)


@dataclass(frozen=True)
class BoxFeatures:
    """The regressor's inputs: :func:`box_features` with ``config`` and ``contexts``. Fitting
    (:mod:`fastdet.train.refine`) and refining (:mod:`fastdet.video.refine`) both take it from
    here, so they compute the same features (and the same offsets, :func:`encode_offsets`)."""

    config: FeatureConfig = REFINE_FEATURES
    contexts: tuple[float, ...] = (1.5,)

    @property
    def n_features(self) -> int:
        return len(self.contexts) * self.config.n_features

    def features(self, frame: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        """``(N, n_features) float64`` of ``boxes (N, 4)`` in ``frame (H, W, 3) uint8 BGR``
        (:func:`box_features`)."""
        return box_features(frame, boxes, self.config, self.contexts)


# ---------------------------------------------------------------------------------------- the model


@dataclass(frozen=True, eq=False)
class BoxRegressor:
    """A linear box regressor (module docstring), one stage or a cascade.

    config: the features of each context crop; contexts: the context factors (> 0);
    coef ``(4, F)``, intercept ``(4,)``, mean ``(F,)``, scale ``(F,)`` float64 with
    ``F = len(contexts) * config.n_features`` (a cascade of ``S`` stages: a leading axis of
    ``S`` on each; stored so, one-stage arrays as ``S = 1``); metadata: what training recorded.
    """

    config: FeatureConfig
    contexts: tuple[float, ...]
    coef: np.ndarray
    intercept: np.ndarray
    mean: np.ndarray
    scale: np.ndarray
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        ctx = tuple(float(c) for c in self.contexts)
        if not ctx or any(not (math.isfinite(c) and c > 0) for c in ctx):
            raise ModelError(f"contexts must be positive numbers, got {self.contexts!r}")
        object.__setattr__(self, "contexts", ctx)
        n = len(ctx) * self.config.n_features
        coef = np.asarray(self.coef)
        stages = coef.shape[0] if coef.ndim == 3 else 1
        if stages < 1:
            raise ModelError("box regressor: a cascade needs at least one stage")
        shapes = {"coef": (4, n), "intercept": (4,), "mean": (n,), "scale": (n,)}
        for name, shape in shapes.items():
            arr = np.ascontiguousarray(getattr(self, name), dtype=np.float64)
            if arr.shape == shape:
                arr = arr[None]
            if arr.shape != (stages,) + shape:
                want = shape if coef.ndim != 3 else (stages,) + shape
                raise ModelError(f"box regressor: '{name}' has shape {arr.shape}, the features "
                                 f"({len(ctx)} contexts x {self.config.n_features}) imply {want}")
            if not np.all(np.isfinite(arr)):
                raise ModelError(f"box regressor: '{name}' holds non-finite values")
            object.__setattr__(self, name, arr)
        if np.any(self.scale <= 0):
            raise ModelError("box regressor: 'scale' must be positive")

    @property
    def n_features(self) -> int:
        return len(self.contexts) * self.config.n_features

    @property
    def spec(self) -> BoxFeatures:
        """The features this regressor takes."""
        return BoxFeatures(self.config, self.contexts)

    @property
    def n_stages(self) -> int:
        """Stages of the cascade (1 for a single regressor)."""
        return int(self.coef.shape[0])

    @classmethod
    def from_fit(cls, spec: BoxFeatures, coef: np.ndarray, intercept: np.ndarray, mean: np.ndarray,
                 scale: np.ndarray, metadata: dict[str, Any] | None = None) -> BoxRegressor:
        """The regressor of ``spec``'s features with fitted arrays (:func:`fastdet.train.refine.fit_ridge`)."""
        return cls(spec.config, spec.contexts, coef, intercept, mean, scale, metadata=dict(metadata or {}))

    @classmethod
    def stack(cls, stages: list[BoxRegressor], metadata: dict[str, Any] | None = None) -> BoxRegressor:
        """The cascade of ``stages`` (each a regressor of the same features, one stage or more),
        in order; ``metadata``: the cascade's."""
        if not stages:
            raise ValueError("stack: no stages given")
        first = stages[0]
        if any(r.spec != first.spec for r in stages):
            raise ValueError("stack: the stages' features differ")
        coef, intercept, mean, scale = (np.concatenate([getattr(r, k) for r in stages])
                                        for k in ("coef", "intercept", "mean", "scale"))
        return cls(first.config, first.contexts, coef, intercept, mean, scale, metadata=dict(metadata or {}))

    @classmethod
    def zero(cls, config: FeatureConfig = REFINE_FEATURES, contexts: tuple[float, ...] = (1.5,)) -> BoxRegressor:
        """A regressor that predicts no change (offsets 0 for every box)."""
        n = len(contexts) * config.n_features
        return cls(config, contexts, np.zeros((4, n)), np.zeros(4), np.zeros(n), np.ones(n))

    def predict_features(self, x: np.ndarray, stage: int = 0) -> np.ndarray:
        """Offsets ``(N, 4) float64`` ``(tx, ty, tw, th)`` of feature rows ``x (N, F)`` by the
        ``stage``-th stage (the last one when ``stage`` is past it)."""
        k = min(max(int(stage), 0), self.n_stages - 1)
        x = np.asarray(x, np.float64).reshape(-1, self.n_features)
        return ((x - self.mean[k]) / self.scale[k]) @ self.coef[k].T + self.intercept[k]

    def predict(self, frame: np.ndarray, boxes: np.ndarray, stage: int = 0) -> np.ndarray:
        """Offsets ``(N, 4) float64`` for ``boxes (N, 4)`` of ``frame (H, W, 3) uint8 BGR`` by
        the ``stage``-th stage (:meth:`predict_features`)."""
        return self.predict_features(self.spec.features(frame, boxes), stage)

    # ---- files ------------------------------------------------------------------------
    def contents(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """``(arrays, metadata)`` as the regressor's file holds them (a model that carries the
        regressor holds the same: :attr:`fastdet.model.Model.regressor`)."""
        meta = dict(self.metadata)
        meta.update(format_version=FORMAT_VERSION, kind="box_regressor", feature_config=self.config.to_dict(),
                    contexts=list(self.contexts), fastdet_version=__version__)
        meta.pop("size_inputs", None)  # a deleted option: a file never says it is on
        arrays = {k: getattr(self, k) for k in ("coef", "intercept", "mean", "scale")}
        if self.n_stages == 1:  # a single regressor's file as it always was
            arrays = {k: v[0] for k, v in arrays.items()}
        meta["stages"] = self.n_stages
        return arrays, meta

    def save(self, path: str | os.PathLike) -> Path:
        """Write to ``path`` (``.npz``), via a temporary file and a rename."""
        return write_npz(path, *self.contents())


def load_regressor(path: str | os.PathLike | None = None) -> BoxRegressor:
    """Load a box regressor (``None``: the bundled :data:`REFINE_MODEL_PATH`).

    Raises :class:`~fastdet.errors.ModelError` (a :class:`~fastdet.errors.FastdetError`)
    naming the problem when the file is missing, not an ``.npz``, holds pickled objects, lacks
    an array, has bad metadata or another format version, or its arrays do not fit its
    features, or lists ``size_inputs`` (written with the box's size among the inputs, a deleted
    option)."""
    path = Path(path) if path is not None else REFINE_MODEL_PATH
    arrays, meta = read_npz(path, _ARRAYS, "box regressor", FORMAT_VERSION)
    return _regressor_of(arrays, meta, str(path))


def _regressor_of(arrays: dict[str, np.ndarray], meta: dict[str, Any], path: str) -> BoxRegressor:
    """The regressor of a file's ``arrays`` and ``meta`` (:meth:`BoxRegressor.contents`);
    ``path`` names it in the messages."""
    if meta.get("kind") != "box_regressor":
        raise ModelError(f"{path} is not a box regressor (metadata kind {meta.get('kind')!r})")
    try:
        config = FeatureConfig.from_dict(meta["feature_config"])
        contexts = tuple(float(c) for c in meta["contexts"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{path}: bad feature configuration in metadata: {exc}") from None
    if meta.get("size_inputs"):
        raise ModelError(f"{path}: written with size inputs {meta['size_inputs']!r} (the box's size among the "
                         "regressor's inputs), an option since deleted: refit it without them")
    try:
        return BoxRegressor(config, contexts, arrays["coef"], arrays["intercept"], arrays["mean"], arrays["scale"],
                            metadata=meta)
    except ModelError as exc:
        raise ModelError(f"{path}: {exc}") from None


def carried_regressor(model: Model, path: str = "the model") -> BoxRegressor | None:
    """The box regressor ``model`` carries (:attr:`fastdet.model.Model.regressor`: one
    ``fastdet adapt`` fitted for the model's camera), ``None`` when it carries none;
    :class:`~fastdet.errors.ModelError` naming ``path`` when it is not a valid regressor."""
    if model.regressor is None:
        return None
    arrays, meta = model.regressor
    version = meta.get("format_version")
    if version != FORMAT_VERSION:
        raise ModelError(f"{path}: its box regressor's format version is {version!r}, this fastdet reads "
                         f"version {FORMAT_VERSION}")
    return _regressor_of(arrays, meta, f"{path} (its box regressor)")


def carrying(model: Model, regressor: BoxRegressor) -> Model:
    """``model`` carrying ``regressor`` (written into its file by :meth:`Model.save`)."""
    return dataclasses.replace(model, regressor=regressor.contents())



"""The linear model: weights, bias, scaler, feature config; a safe file format.

A model file is an ``.npz`` archive of plain arrays, read with ``allow_pickle=False`` so
it can never run code:

===============  ============================  =========================================
array            shape, dtype                  meaning
===============  ============================  =========================================
``coef``         ``(F,) float64``              classifier weights on scaled features
``intercept``    ``() float64``                classifier bias
``mean``         ``(F,) float64``              StandardScaler ``mean_``
``scale``        ``(F,) float64``              StandardScaler ``scale_``
``metadata``     ``(n,) uint8``                UTF-8 JSON: format version, FeatureConfig,
                                               classifier, metrics, data counts, version
===============  ============================  =========================================

``score(x) = coef · (x - mean) / scale + intercept``; > 0 means vehicle. The detector folds
the scaler into the weights once (:meth:`Model.folded`).

A model made for one camera (``fastdet adapt``) also carries the box regressor fitted for that
camera: its arrays as ``regressor_coef``, ``regressor_intercept``, ``regressor_mean``,
``regressor_scale`` and its metadata under ``metadata["regressor"]``, as a regressor file of its
own holds them (:mod:`fastdet.detect.regressor`); the video pipeline then refines boxes with it
(:func:`fastdet.video.refine.regressor_for`). It may also carry a side-view component
(:attr:`Model.side`): a second linear model of wide windows (64x32) for the vehicles seen side-on
that a square window does not fit, its arrays as ``side_coef``, ``side_intercept``, ``side_mean``,
``side_scale`` and its feature config, classifier and metadata under ``metadata["side"]``; a
:class:`fastdet.Detector` searches with it beside the main model.
"""
from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ._version import __version__
from .config import FeatureConfig, ScoreKind
from .config.models import DEFAULT_MODEL_PATH, ONCOMING_MODEL_PATH  # noqa: F401  (the bundled models, named here too)
from .errors import DataError, ModelError
from .features import extract_features
from .io.atomic import atomic_path
from .io.files import open_input, parse_json

FORMAT_VERSION = 1
CLASSIFIERS = ("linearsvc", "logreg")
_ARRAYS = ("coef", "intercept", "mean", "scale", "metadata")
#: the arrays of a carried box regressor (:attr:`Model.regressor`) in a model file, by their
#: names in a regressor file
CARRIED = {k: f"regressor_{k}" for k in ("coef", "intercept", "mean", "scale")}
#: the arrays of a carried side-view component (:attr:`Model.side`) in a model file, by their
#: names in a model file of its own
SIDE_ARRAYS = {k: f"side_{k}" for k in ("coef", "intercept", "mean", "scale")}
#: the largest ``metadata`` array (JSON bytes) a model or regressor file may declare (the
#: bundled ones hold 1-3 KB)
MAX_METADATA_BYTES = 16 * 2**20
#: the largest any other array of a model file may declare (the bundled ones: 100 KB; a
#: window's features are bounded by :data:`~fastdet.config.features.MAX_FEATURES`)
MAX_ARRAY_BYTES = 64 * 2**20
#: the largest magnitude of a weight, a mean, the intercept and a folded weight
#: ``coef / scale`` (the bundled models: below 2,000); and the smallest ``scale``. Past them a
#: window's score overflows to infinity or NaN (``scale 1e-310``, ``coef 1e308``)
MAX_ABS_VALUE = 1e12
MIN_SCALE = 1e-12


@dataclass(frozen=True, eq=False)
class Model:
    """A trained linear window classifier.

    config: the features it expects (64x64 BGR crops → ``config.n_features`` values).
    coef, mean, scale: ``(F,) float64``; intercept: float.
    classifier: ``'linearsvc'`` (score = decision value) or ``'logreg'`` (also probabilities).
    metadata: everything else recorded at training time (metrics, data counts, ...).
    regressor: the box regressor this model's camera uses, as its file holds it: ``(arrays,
        metadata)`` (:meth:`fastdet.detect.regressor.BoxRegressor.contents`; ``None``: none, the
        pipeline's own). Kept as plain arrays here: the regressor's code lives a layer above.
    side: the camera's side-view component (``fastdet adapt``): a model of wide windows
        (``config.window_height`` < ``config.window``) of the same classifier, searched by
        :class:`fastdet.Detector` at the main model's bands beside it (its windows tagged
        ``FIRST_COMPONENT_PART``); ``None``: none. It carries nothing itself.
    """

    config: FeatureConfig
    coef: np.ndarray
    intercept: float
    mean: np.ndarray
    scale: np.ndarray
    classifier: Literal["linearsvc", "logreg"] = "linearsvc"
    metadata: dict[str, Any] = field(default_factory=dict)
    regressor: tuple[dict[str, np.ndarray], dict[str, Any]] | None = None
    side: Model | None = None

    def __post_init__(self) -> None:
        if self.side is not None:
            if not isinstance(self.side, Model) or self.side.side is not None or self.side.regressor is not None:
                raise ModelError("a side-view component must be a Model that carries nothing itself")
            sc, mc = self.side.config, self.config
            if sc.window_height is None or sc.window_height >= sc.window:
                raise ModelError("a side-view component must be a wide-window model (wider than tall)")
            if replace(sc, window_height=None) != replace(mc, window_height=None):
                raise ModelError("a side-view component must have the main model's features (at a wider window): "
                                 "it scores the main model's band images and HOG")
            if self.side.classifier != self.classifier:
                raise ModelError(f"the side-view component is a {self.side.classifier} model, the main model a "
                                 f"{self.classifier} one: their scores would not compare")
        if self.regressor is not None and (set(self.regressor[0]) != set(CARRIED)
                                           or not isinstance(self.regressor[1], dict)):
            raise ModelError(f"a carried box regressor needs the arrays {sorted(CARRIED)} and a metadata dict")
        n = self.config.n_features
        for name in ("coef", "mean", "scale"):
            arr = np.ascontiguousarray(getattr(self, name), dtype=np.float64)
            if arr.shape != (n,):
                raise ModelError(
                    f"feature config mismatch: '{name}' has shape {arr.shape}, the feature config "
                    f"{self.config} implies ({n},)")
            if not np.all(np.isfinite(arr)):
                raise ModelError(f"'{name}' holds non-finite values")
            object.__setattr__(self, name, arr)
        if np.any(self.scale == 0):
            raise ModelError("'scale' holds zeros")
        for name in ("coef", "mean"):
            big = float(np.max(np.abs(getattr(self, name)), initial=0.0))
            if big > MAX_ABS_VALUE:
                raise ModelError(f"'{name}' holds {big:.3g}, beyond the +-{MAX_ABS_VALUE:.0e} a model's values may "
                                 f"take (a window's score would overflow)")
        small = float(np.min(np.abs(self.scale), initial=np.inf))
        if small < MIN_SCALE or float(np.max(np.abs(self.scale), initial=0.0)) > MAX_ABS_VALUE:
            raise ModelError(f"'scale' holds values outside [{MIN_SCALE:.0e}, {MAX_ABS_VALUE:.0e}] "
                             f"(the smallest is {small:.3g}): the folded weights would overflow")
        folded = float(np.max(np.abs(self.coef / self.scale), initial=0.0))
        if not folded <= MAX_ABS_VALUE:
            raise ModelError(f"'coef' / 'scale' reaches {folded:.3g}, beyond +-{MAX_ABS_VALUE:.0e} (a window's "
                             f"score would overflow)")
        object.__setattr__(self, "intercept", float(self.intercept))
        if not abs(self.intercept) <= MAX_ABS_VALUE:
            raise ModelError(f"'intercept' is {self.intercept:.3g}, beyond +-{MAX_ABS_VALUE:.0e}")
        if self.classifier not in CLASSIFIERS:
            raise ModelError(f"unknown classifier {self.classifier!r}; expected one of {CLASSIFIERS}")

    # ---- scoring -----------------------------------------------------------------------
    @property
    def score_kind(self) -> ScoreKind:
        """``'probability'`` for logistic regression, ``'decision'`` for the SVM."""
        return "probability" if self.classifier == "logreg" else "decision"

    def folded(self) -> tuple[np.ndarray, float]:
        """The scaler folded into the weights: ``(w', b')`` with ``score = w'·x + b'``."""
        w = self.coef / self.scale
        b = self.intercept - float(np.dot(self.coef, self.mean / self.scale))
        return w, b

    def decision_from_features(self, features: np.ndarray) -> np.ndarray:
        """Decision values of ``(N, F)`` raw feature vectors: ``(N,) float64``."""
        x = (np.asarray(features, np.float64) - self.mean) / self.scale
        return x @ self.coef + self.intercept

    def decision_function(self, crops: np.ndarray) -> np.ndarray:
        """Decision values of ``(N, 64, 64, 3) uint8`` BGR crops: ``(N,) float64``, > 0 is vehicle."""
        crops = np.asarray(crops)
        single = crops.ndim == 3
        scores = self.decision_from_features(extract_features(crops[None] if single else crops, self.config))
        return scores[0] if single else scores

    def predict(self, crops: np.ndarray) -> np.ndarray:
        """``1`` (vehicle) where the decision value is > 0, else ``0``; ``(N,) int64``."""
        return (self.decision_function(crops) > 0).astype(np.int64)

    def predict_proba(self, crops: np.ndarray) -> np.ndarray:
        """``(N, 2)`` probabilities ``[non-vehicle, vehicle]`` (logistic regression only)."""
        if self.classifier != "logreg":
            raise AttributeError("predict_proba needs a logistic-regression model (this one is a LinearSVC)")
        p = 1.0 / (1.0 + np.exp(-self.decision_function(crops)))
        return np.stack([1 - p, p], axis=-1)

    # ---- files -------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> Path:
        """Write the model to ``path`` (``.npz``), via a temporary file and a rename."""
        meta = dict(self.metadata)
        meta.update(format_version=FORMAT_VERSION, feature_config=self.config.to_dict(),
                    classifier=self.classifier, fastdet_version=__version__)
        arrays: dict[str, np.ndarray | np.generic] = {"coef": self.coef, "intercept": np.float64(self.intercept),
                                                      "mean": self.mean, "scale": self.scale}
        meta.pop("regressor", None)
        if self.regressor is not None:
            arrays.update({CARRIED[k]: v for k, v in self.regressor[0].items()})
            meta["regressor"] = self.regressor[1]
        meta.pop("side", None)
        if self.side is not None:
            sd = self.side
            arrays.update({SIDE_ARRAYS["coef"]: sd.coef, SIDE_ARRAYS["intercept"]: np.float64(sd.intercept),
                           SIDE_ARRAYS["mean"]: sd.mean, SIDE_ARRAYS["scale"]: sd.scale})
            meta["side"] = {**sd.metadata, "feature_config": sd.config.to_dict(), "classifier": sd.classifier}
        return write_npz(path, arrays, meta)


def write_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray | np.generic], meta: dict[str, Any]) -> Path:
    """Write ``arrays`` and ``meta`` (as the ``metadata`` array: UTF-8 JSON bytes, ``uint8``) to
    ``path`` (``.npz``), via a temporary file and a rename (:func:`fastdet.io.atomic.atomic_path`):
    the format of model files and of the box regressor."""
    path = Path(path)
    blob = np.frombuffer(json.dumps(meta, sort_keys=True).encode("utf-8"), dtype=np.uint8)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            payload: dict[str, Any] = {**arrays, "metadata": blob}
            np.savez_compressed(fh, **payload)
    return path


def read_npz(path: Path, names: tuple[str, ...], what: str = "model",
             version: int = FORMAT_VERSION,
             max_array_bytes: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays ``names`` (``metadata`` among them) and the parsed metadata of a file written
    by :func:`write_npz`, read with ``allow_pickle=False``. ``what`` names the kind of file in
    the messages (``'model'``, ``'box regressor'``).

    Raises :class:`~fastdet.errors.ModelError` naming the problem when the file is missing, a
    folder, unreadable, not an ``.npz``, truncated, holds pickled objects, lacks an array, has
    metadata that is not a JSON object or of another ``format_version`` than ``version``, or an
    array other than the metadata holds non-numbers. ``max_array_bytes``: the budget of an array
    other than the metadata (default :data:`MAX_ARRAY_BYTES`; a work file such as the
    verifier's first-stage cache holds more than a model's)."""
    if path.is_dir():
        raise ModelError(f"{what} path {path} is a folder, not a file (an .npz is expected)")
    if not path.exists() and not path.is_symlink():
        raise ModelError(f"{what} file {path} not found")
    try:
        fh = open_input(path, f"{what} file")  # a FIFO, a device, a symlink loop: one line, no wait
    except DataError as exc:
        raise ModelError(f"{what} file {exc}") from None
    with fh:
        return _read_npz(fh, path, names, what, version, max_array_bytes)


def _read_npz(fh: Any, path: Path, names: tuple[str, ...], what: str,
              version: int, max_array_bytes: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """:func:`read_npz` of the opened file ``fh``."""
    try:
        magic = fh.read(4)
        fh.seek(0)
    except OSError as exc:
        raise ModelError(f"{what} file {path}: cannot read ({exc.strerror or exc})") from None
    if magic != b"PK\x03\x04":
        raise ModelError(f"{path} is not a fastdet {what}: not an .npz (zip) archive"
                         + (" (empty file)" if not magic else ""))
    _check_members(fh, path, names, what, max_array_bytes)
    fh.seek(0)
    try:
        with np.load(fh, allow_pickle=False) as npz:
            if not isinstance(npz, np.lib.npyio.NpzFile):
                raise ModelError(f"{path} is a single .npy array, not a fastdet {what} (.npz)")
            missing = [k for k in names if k not in npz.files]
            if missing:
                raise ModelError(f"{path} is not a fastdet {what}: missing array(s) {', '.join(missing)}")
            arrays = {k: npz[k] for k in names}
    except ModelError:
        raise
    except ValueError as exc:
        if "pickle" in str(exc):
            raise ModelError(f"{path} holds a pickled object array; fastdet {what}s hold plain numeric "
                             "arrays only and are never unpickled") from None
        raise ModelError(f"{path} is not a readable .npz {what} file (truncated or another format): {exc}") from None
    except OSError as exc:
        raise ModelError(f"{what} file {path}: cannot read ({exc.strerror or exc})") from None
    except (zipfile.BadZipFile, EOFError, KeyError) as exc:
        raise ModelError(f"{path} is not a readable .npz {what} file (truncated or another format): {exc}") from None
    try:
        meta = parse_json(arrays["metadata"].astype(np.uint8).tobytes())
        if not isinstance(meta, dict):
            raise ValueError("not a JSON object")
    except ValueError as exc:  # JsonError: a syntax error, nesting too deep, a number too long, not UTF-8
        raise ModelError(f"{path}: metadata is not valid JSON: {exc}") from None
    found = meta.get("format_version")
    if found != version or isinstance(found, bool):
        if not isinstance(found, int) or isinstance(found, bool):
            raise ModelError(f"{path}: the {what}'s format version must be the number {version}, "
                             f"got {type(found).__name__} {json.dumps(found)}")
        raise ModelError(f"{path}: {what} format version {found}, this fastdet reads version {version}")
    for name in names:
        if name != "metadata" and arrays[name].dtype.kind not in "fiu":
            raise ModelError(f"{path}: '{name}' holds {arrays[name].dtype} values, expected numbers")
        if name != "metadata" and not np.all(np.isfinite(arrays[name])):
            raise ModelError(f"{path}: '{name}' holds values that are not finite numbers (NaN or infinity)")
    return arrays, meta


def _check_members(fh: Any, path: Path, names: tuple[str, ...], what: str,
                   max_array_bytes: int | None = None) -> None:
    """Each array ``names`` of the archive (the open file ``fh``) has a valid ``.npy`` header of
    a plain dtype whose shape fits the bytes stored (a header may claim any shape: reading it
    would allocate that much before noticing) and the memory budget
    (:data:`MAX_METADATA_BYTES`, :data:`MAX_ARRAY_BYTES`: 250 M zeros compress to 2 MB).
    ``ModelError`` otherwise; a damaged archive is left to ``np.load``'s own checks."""
    try:
        zf = zipfile.ZipFile(fh)
    except (zipfile.BadZipFile, OSError, EOFError, ValueError):
        return
    with zf:
        for name in names:
            try:
                info = zf.getinfo(f"{name}.npy")
            except KeyError:
                continue  # reported as missing by the caller
            try:
                with zf.open(info) as fh:
                    version = np.lib.format.read_magic(fh)
                    if version == (1, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
                    elif version == (2, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
                    else:
                        raise ValueError(f"unsupported .npy version {version}")
                    header = fh.tell()
            except (ValueError, OSError, EOFError, zipfile.BadZipFile, SyntaxError, TypeError) as exc:
                raise ModelError(f"{path} is not a fastdet {what}: '{name}' is not a valid .npy array "
                                 f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
            if dtype.hasobject:
                raise ModelError(f"{path} holds a pickled object array; fastdet {what}s hold plain numeric "
                                 "arrays only and are never unpickled")
            need = int(np.prod(shape, dtype=object)) * dtype.itemsize
            if need > info.file_size - header:
                raise ModelError(f"{path} is not a readable .npz {what} file: '{name}' claims shape {shape} "
                                 f"({need} bytes) but holds {info.file_size - header} bytes")
            budget = MAX_METADATA_BYTES if name == "metadata" else (
                MAX_ARRAY_BYTES if max_array_bytes is None else max_array_bytes)
            if need > budget:
                raise ModelError(f"{path} is not a usable fastdet {what}: '{name}' declares shape {shape} "
                                 f"({need} bytes), more than the {budget // 2**20} MB such an array may hold")


def load_model(path: str | os.PathLike | None = None, expected_config: FeatureConfig | None = None) -> Model:
    """Load a model file (``None``: the bundled default model).

    Raises :class:`~fastdet.errors.ModelError` naming the problem when the file is missing,
    truncated, not an ``.npz``, of another format version, or its weights do not fit its
    feature configuration (or ``expected_config`` when given).
    """
    path = Path(path) if path is not None else DEFAULT_MODEL_PATH
    arrays, meta = read_npz(path, _ARRAYS, "model")
    try:
        config = FeatureConfig.from_dict(meta["feature_config"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{path}: bad feature configuration in metadata: {exc}") from None
    if expected_config is not None and config != expected_config:
        raise ModelError(f"{path}: feature config mismatch: the model uses {config}, expected {expected_config}")
    if arrays["intercept"].shape != ():
        raise ModelError(f"{path}: 'intercept' must be a scalar, got shape {arrays['intercept'].shape}")
    regressor = None
    if "regressor" in meta:
        if not isinstance(meta["regressor"], dict):
            raise ModelError(f"{path}: metadata 'regressor' must be a JSON object, got {meta['regressor']!r:.60}")
        carried, _ = read_npz(path, (*CARRIED.values(), "metadata"), "model")
        regressor = ({k: carried[v] for k, v in CARRIED.items()}, meta["regressor"])
    side = _load_side(path, meta) if "side" in meta else None
    try:
        return Model(config=config, coef=arrays["coef"], intercept=float(arrays["intercept"]),
                     mean=arrays["mean"], scale=arrays["scale"],
                     classifier=meta.get("classifier", "linearsvc"), metadata=meta, regressor=regressor, side=side)
    except ModelError as exc:
        raise ModelError(f"{path}: {exc}") from None


def _load_side(path: Path, meta: dict[str, Any]) -> Model:
    """The side-view component a model file carries (:data:`SIDE_ARRAYS`, ``metadata["side"]``)."""
    sm = meta["side"]
    if not isinstance(sm, dict):
        raise ModelError(f"{path}: metadata 'side' must be a JSON object, got {sm!r:.60}")
    try:
        config = FeatureConfig.from_dict(sm["feature_config"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{path}: bad feature configuration of the side-view component: {exc}") from None
    arrays, _ = read_npz(path, (*SIDE_ARRAYS.values(), "metadata"), "model")
    if arrays[SIDE_ARRAYS["intercept"]].shape != ():
        raise ModelError(f"{path}: '{SIDE_ARRAYS['intercept']}' must be a scalar")
    try:
        return Model(config=config, coef=arrays[SIDE_ARRAYS["coef"]], intercept=float(arrays[SIDE_ARRAYS["intercept"]]),
                     mean=arrays[SIDE_ARRAYS["mean"]], scale=arrays[SIDE_ARRAYS["scale"]],
                     classifier=sm.get("classifier", "linearsvc"), metadata=sm)
    except ModelError as exc:
        raise ModelError(f"{path}: side-view component: {exc}") from None

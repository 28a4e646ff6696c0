"""What :class:`~fastdet.VideoDetector` needs of a detector (:class:`WindowDetector`), the
optional abilities it uses when a detector has them (:class:`MovableHorizon`,
:class:`ColumnSearch`), and the pipeline's own detector (:func:`make_detector`)."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np

from ..config import BOXES, Boxes, Horizon, PipelineConfig, SearchBand, oncoming_search
from ..config.models import DEFAULT_MODEL_PATH, ONCOMING_MODEL_PATH
from ..detect import BandGeometry, Detector, DetectStats
from ..detections import Detections
from ..errors import ModelError
from ..model import Model, read_npz


@runtime_checkable
class WindowDetector(Protocol):
    """What :class:`~fastdet.VideoDetector` needs of a detector (:class:`fastdet.Detector` is one).

    ``score_kind``: ``"probability"`` or ``"decision"`` (how the heat map scales scores);
    ``oncoming_model``: the oncoming-traffic (wide-window) model or ``None``; ``detect`` returns
    the positive windows with the ``part`` column set (or no ``part``: all main-model
    windows); ``geometries(shape, part=1)`` the oncoming model's bands (used only when
    ``oncoming_model`` is not ``None``, for the motion gate).

    Optional abilities, used when the detector has them: :class:`MovableHorizon` (the bands
    follow the horizon), :class:`ColumnSearch` (the guided search) and :class:`HasKernels`
    (its numba kernels compiled with the pipeline's at warm-up)."""

    @property
    def score_kind(self) -> str: ...

    @property
    def oncoming_model(self) -> Model | None: ...

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands: Sequence[SearchBand] | None = None,
               stats: DetectStats | None = None) -> Detections: ...

    def warmup(self) -> None: ...

    def geometries(self, frame_shape: tuple[int, int], part: int = 0) -> list[BandGeometry]: ...


@runtime_checkable
class MovableHorizon(Protocol):
    """A detector whose search bands move with the horizon: ``horizon`` (a fraction of the
    frame height, ``None``: where the search writes it) and ``set_horizon(h)``."""

    @property
    def horizon(self) -> float | None: ...

    def set_horizon(self, horizon: float | None) -> None: ...


@runtime_checkable
class ColumnSearch(Protocol):
    """A detector that scores only some windows of its main bands: ``column_search`` is
    ``True``, ``detect`` takes ``columns`` (one entry per band of ``geometries(shape, 0)``:
    ``None`` for all, else window-column ranges ``(j0, j1)``) and ``config`` is the main
    model's :class:`~fastdet.config.FeatureConfig` (window and cell size)."""

    column_search: Literal[True]

    def detect(self, frame: np.ndarray, rgb: bool = False, oncoming_bands: Sequence[SearchBand] | None = None,
               stats: DetectStats | None = None,
               columns: Sequence[Sequence[tuple[int, int]] | None] | None = None) -> Detections: ...


@runtime_checkable
class HasKernels(Protocol):
    """A detector that names the numba kernels its ``detect`` runs (``kernels``), so a
    warm-up compiles them at once with the rest of the pipeline's
    (:func:`fastdet._numba.ensure_compiled`)."""

    kernels: tuple[Any, ...]


#: the main model file's metadata key that records the box formation its camera was adapted
#: with (:func:`box_formation`)
BOXES_KEY = "video_boxes"


def box_formation(config: PipelineConfig, detector: object) -> Boxes:
    """How the pipeline for ``config`` makes one box per vehicle (:attr:`PipelineConfig.boxes`):
    ``config.boxes`` when set; else what ``detector``'s main model records (its ``model``'s
    metadata :data:`BOXES_KEY`: ``fastdet adapt`` writes the formation it chose for the
    camera); else ``'heat'``. :class:`~fastdet.errors.ModelError` for a record that is not one."""
    model = getattr(detector, "model", None)
    return recorded_formation(config, model.metadata if isinstance(model, Model) else {})


def recorded_formation(config: PipelineConfig, metadata: Mapping[str, Any]) -> Boxes:
    """:func:`box_formation` for the main model whose file's ``metadata`` this is."""
    if config.boxes is not None:
        return config.boxes
    got = metadata.get(BOXES_KEY)
    if got is None:
        return "heat"
    if got not in BOXES:
        raise ModelError(f"the main model's metadata['{BOXES_KEY}'] must be one of {', '.join(BOXES)}, got {got!r}")
    return got


#: the main model file's metadata key that records the horizon of the camera the model was adapted
#: to (a fraction of the frame height), where ``fastdet adapt`` found its labelled vehicles' boxes
#: put it better than the flow of the video does (:func:`camera_horizon`)
HORIZON_KEY = "video_horizon"


def camera_horizon(config: PipelineConfig, detector: object) -> Horizon:
    """Where the pipeline for ``config`` puts the search bands (:attr:`PipelineConfig.horizon`):
    :func:`recorded_horizon` of ``detector``'s main model (its ``model``'s metadata; a detector
    without one records nothing). :class:`~fastdet.errors.ModelError` for a bad record."""
    model = getattr(detector, "model", None)
    return recorded_horizon(config.horizon, model.metadata if isinstance(model, Model) else {})


def recorded_horizon(horizon: Horizon, metadata: Mapping[str, Any]) -> Horizon:
    """Where the bands go for the pipeline's ``horizon`` setting (:attr:`PipelineConfig.horizon`)
    with a main model whose file's ``metadata`` this is: ``horizon`` unless it is ``'auto'`` and
    the model records its camera's horizon (:data:`HORIZON_KEY`, written by ``fastdet adapt``):
    then that number, for every video, not one estimated from each video's flow.
    :class:`~fastdet.errors.ModelError` for a record that is not a fraction of the height."""
    if horizon != "auto":
        return horizon
    got = metadata.get(HORIZON_KEY)
    if got is None:
        return "auto"
    if isinstance(got, bool) or not isinstance(got, (int, float)) or not 0.0 < got < 1.0:
        raise ModelError(f"the main model's metadata['{HORIZON_KEY}'] must be a fraction of the frame height "
                         f"in (0, 1), got {got!r}")
    return float(got)


def main_model_records(config: PipelineConfig) -> dict[str, Any]:
    """The metadata of ``config``'s main model file (the bundled one when none is given), read
    alone: the arrays are not loaded. :class:`~fastdet.errors.ModelError` when it does not read."""
    _, meta = read_npz(Path(config.model) if config.model is not None else DEFAULT_MODEL_PATH, ("metadata",))
    return meta


#: the main model file's metadata key that records whether the bundled oncoming-traffic model runs
#: beside it (:func:`make_detector`): ``fastdet adapt`` writes ``False``, as the camera's own model
#: finds that traffic itself (docs/training.md, "The oncoming model beside an adapted model")
ONCOMING_KEY = "video_oncoming"


def recorded_oncoming(metadata: Mapping[str, Any]) -> bool:
    """Whether the bundled oncoming model runs beside the main model whose file's ``metadata``
    this is, when the pipeline's :attr:`PipelineConfig.oncoming` is ``True`` (the default): what
    the model records (:data:`ONCOMING_KEY`), else ``True``. :class:`~fastdet.errors.ModelError`
    for a record that is not ``True`` or ``False``."""
    got = metadata.get(ONCOMING_KEY, True)
    if not isinstance(got, bool):
        raise ModelError(f"the main model's metadata['{ONCOMING_KEY}'] must be true or false, got {got!r}")
    return got


def detector_kernels(detector: object) -> tuple[Any, ...]:
    """The numba kernels of ``detector`` (:class:`HasKernels`; none for another detector)."""
    return tuple(detector.kernels) if isinstance(detector, HasKernels) else ()


def make_detector(config: PipelineConfig | None = None) -> Detector:
    """The video pipeline's :class:`fastdet.Detector` for ``config`` (default
    ``PipelineConfig()``): its main model and search, and its oncoming-traffic model
    searching the side of the view :attr:`PipelineConfig.traffic` puts oncoming cars on
    (:func:`fastdet.config.oncoming_search`); with ``oncoming=True`` (the bundled one), none
    when the main model records so (:func:`recorded_oncoming`: an adapted camera's). A main model
    carrying a side-view component searches with it when the boxes are the window boxes
    (:func:`box_formation`), not for the heat map, which takes the main model's windows only. Raises
    :class:`~fastdet.errors.ModelError` when a model does not load."""
    c = config if config is not None else PipelineConfig()
    meta = main_model_records(c)  # the records alone: the Detector loads and checks the model, once
    oncoming: str | Path | None
    if c.oncoming is True:
        oncoming = ONCOMING_MODEL_PATH if recorded_oncoming(meta) else None
    else:
        oncoming = c.oncoming or None
    # the heat map takes the main model's windows only: a side-view component, chosen for the
    # window boxes, would be searched for nothing
    return Detector(model=c.model, search=c.search, oncoming=oncoming, oncoming_search=oncoming_search(c.traffic),
                    side=recorded_formation(c, meta) == "nms")

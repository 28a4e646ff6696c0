"""Search bands from the camera's geometry (:class:`GeometryConfig`,
:mod:`fastdet.detect.geometry`) and the perspective learnt from the video's own vehicles
(:class:`PerspectiveConfig`, :mod:`fastdet.video.perspective`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from ._base import Config


@dataclass(frozen=True)
class GeometryConfig(Config):
    """How search bands follow the camera's geometry (:mod:`fastdet.detect.geometry`).

    reference_ratio: the ratio of the camera the reference bands were tuned on (1.9; how it
        was measured: docs/geometry.md).
    ratio: the prior ratio, used until the video's own vehicles give one.
    slack: rows added above and below every band, a fraction of the frame height: the
        horizon error a band survives without losing a window that finds a vehicle.
    """

    reference_ratio: float = 1.9
    ratio: float = 1.9
    slack: float = 0.05

    def __post_init__(self) -> None:
        if not self.ratio > 0 or not self.reference_ratio > 0:
            raise ValueError(f"ratio and reference_ratio must be > 0, got {self.ratio!r}, {self.reference_ratio!r}")
        if not 0 <= self.slack < 1:
            raise ValueError(f"slack must be a fraction of the frame height in [0, 1), got {self.slack!r}")


@dataclass(frozen=True)
class PerspectiveConfig(Config):
    """Settings of :class:`fastdet.video.perspective.PerspectiveUpdater`: the main search follows
    the horizon and ratio the tracked vehicles show (``tools/studies/geometry_study.py --joint``;
    no longer a stage of the pipeline: docs/geometry.md).

    geometry: the bands' geometry (reference ratio, prior ratio); its ``slack`` is the slack
        until there is an estimate.
    settled_slack: the slack once there is one (fraction of the frame height).
    min_score: the score a tracked box needs to count (the heat map's peak).
    min_boxes, min_tracks, long_track: tracks of at least ``min_boxes`` such boxes, at least
        ``min_tracks`` of them (or one track of ``long_track`` boxes; ``None``: never), before
        there is an estimate.
    sigma_h: how far (fraction of the height) the estimate may pull the horizon from the
        prior without cost (one standard deviation of the prior).
    sigma_ratio: the same for the ratio, in log units.
    residuals: how a box's misfit is measured (:class:`fastdet.detect.geometry.PerspectiveEstimator`):
        ``'log'`` (its log ratio against its track's) or ``'rows'`` (its bottom row against
        the one its width puts it on: steadier near the horizon; docs/geometry.md).
    prior_frames: frames the slack is kept while no estimate comes (``None``: until one
        comes); then the bands stay at the prior without slack (a video that shows too few
        vehicles to say where the road is does not pay for the slack for ever).
    """

    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    settled_slack: float = 0.0
    min_score: float = 10.0
    min_boxes: int = 5
    min_tracks: int = 2
    long_track: int | None = None
    sigma_h: float = 0.04
    sigma_ratio: float = 0.5
    prior_frames: int | None = None
    residuals: Literal["rows", "log"] = "log"

    def __post_init__(self) -> None:
        if self.residuals not in ("rows", "log"):
            raise ValueError(f"residuals must be 'rows' or 'log', got {self.residuals!r}")
        if not 0 <= self.settled_slack < 1:
            raise ValueError(f"settled_slack must be in [0, 1), got {self.settled_slack!r}")
        if self.min_boxes < 1 or self.min_tracks < 1:
            raise ValueError("min_boxes and min_tracks must be >= 1")
        if not self.sigma_h > 0 or not self.sigma_ratio > 0:
            raise ValueError("sigma_h and sigma_ratio must be > 0")
        if self.prior_frames is not None and self.prior_frames < 0:
            raise ValueError(f"prior_frames must be >= 0 or None, got {self.prior_frames!r}")

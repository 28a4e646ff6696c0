"""The own vehicle in the picture (hood, dashboard, mirrors, letterbox bars) and the
positive windows dropped on it (:class:`OwnVehicleConfig`)."""
from __future__ import annotations

from dataclasses import dataclass

from ._base import Config


@dataclass(frozen=True)
class OwnVehicleConfig(Config):
    """Where the own vehicle is and what is dropped there (:mod:`fastdet.video.ownvehicle`;
    how the defaults were measured: docs/ownvehicle_neighbours.md). Off unless given to
    :attr:`PipelineConfig.own_vehicle <fastdet.config.PipelineConfig>`.

    work_rows: frames are shrunk to this many rows (grey) for the estimate.
    gap_s: seconds between the two frames of a pair (0.3: 8 frames at 25 fps; the scene must
        move by a pixel or more in that time for a car at highway or city speed).
    every: one pair per this many frames.
    frames_s: seconds of video the estimate is made from (then fixed).
    min_gradient: grey levels per work pixel for a textured pixel.
    max_change: grey levels a still pixel may change by between the pair's frames
        (compression noise, flicker).
    min_moving: fraction of the textured pixels that must change for the pair to count.
    min_pairs: fewest counted pairs for an estimate (fewer: no region).
    cells: cells across the width (the region's resolution).
    min_texture: a cell decides only when on average at least this fraction of its pixels
        was textured over the counted pairs.
    min_still: fraction of a cell's textured pixels that were still for a fixed cell.
    bar_level: grey level below which a border row or column is a letterbox bar (on every
        sampled frame, every pixel of it).
    max_fraction: a positive window with at least this fraction of its area in the region
        is dropped.
    max_area: a region larger than this fraction of the frame is not the own vehicle (a
        camera that stood still while a few vehicles moved through): no region.
    """

    work_rows: int = 180
    gap_s: float = 0.3
    every: int = 3
    frames_s: float = 3.0
    min_gradient: float = 24.0
    max_change: float = 8.0
    min_moving: float = 0.15
    min_pairs: int = 5
    cells: int = 40
    min_texture: float = 0.05
    min_still: float = 0.8
    bar_level: float = 20.0
    max_fraction: float = 0.5
    max_area: float = 0.5

    def __post_init__(self) -> None:
        for name, least in (("work_rows", 16), ("every", 1), ("min_pairs", 1), ("cells", 4)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < least:
                raise ValueError(f"{name} must be an integer >= {least}, got {v!r}")
        for name in ("gap_s", "frames_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0 seconds, got {getattr(self, name)!r}")
        for name in ("min_gradient", "max_change", "bar_level"):
            if not 0 <= getattr(self, name) <= 255:
                raise ValueError(f"{name} must be in [0, 255] grey levels, got {getattr(self, name)!r}")
        for name in ("min_moving", "min_texture", "min_still", "max_fraction", "max_area"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")

    def gap(self, fps: float | None) -> int:
        """Frames between a pair's two frames at ``fps`` (``None``: 25)."""
        return max(1, round(self.gap_s * (fps or 25.0)))

    def n_frames(self, fps: float | None) -> int:
        """Frames the estimate is made from at ``fps`` (``None``: 25)."""
        return max(2, round(self.frames_s * (fps or 25.0)))

"""Heat blobs over vehicles side by side split into one box each (:class:`NeighbourSplit`)."""
from __future__ import annotations

from dataclasses import dataclass

from ._base import Config


@dataclass(frozen=True)
class NeighbourSplit(Config):
    """When and where a main heat-map box is split between the modes of its blob's windows
    (:mod:`fastdet.video.blobsplit`; how the defaults were measured:
    docs/ownvehicle_neighbours.md). Off unless given to :attr:`PipelineConfig.split
    <fastdet.config.PipelineConfig>`.

    min_aspect: only boxes at least this many times as wide as tall are looked at (a
        vehicle's rear is not that wide; at 1.4 the halves of a large near car were split).
    min_weight: modes lighter than this fraction of the heaviest one do not count.
    bandwidth: the mean shift's sigma in x and y, as a fraction of the window width.
    scale_bandwidth: its sigma in log2 window width.
    inside: a mode with at least this fraction of its box inside a heavier mode's box is a
        part of that vehicle.
    max_overlap: two neighbouring modes are two vehicles when their boxes overlap along x by
        at most this fraction of the narrower one.
    min_heat: a mode lighter than ``min_weight`` x the heaviest still counts when its windows'
        summed heat (window heat, :meth:`fastdet.video.heatmap.HeatMap.window_heat`) is above
        ``min_heat`` x the heat map's threshold: its windows alone would make a blob in one
        frame (a smaller car beside a near one gathers fewer windows). ``None``: never.
    max_frame_windows: at most this many windows go into the mean shift in one frame (each
        blob gives at most ``blobsplit.MAX_WINDOWS``, the heaviest blobs first; a blob that
        no longer fits keeps its heat box whole): the split's cost a frame is bounded on a
        frame of many big blobs over dense texture. The annotated clips stay far below it.
    """

    _OMIT_NONE = ("min_heat",)  # configs written before it existed keep their digest
    _OMIT_DEFAULT = {"max_frame_windows": 512}

    min_aspect: float = 1.8
    min_weight: float = 0.5
    bandwidth: float = 0.25
    scale_bandwidth: float = 0.3
    inside: float = 0.5
    max_overlap: float = 0.3
    min_heat: float | None = None
    max_frame_windows: int = 512

    def __post_init__(self) -> None:
        for name in ("min_aspect", "bandwidth", "scale_bandwidth"):
            if not 0 < getattr(self, name) < 100:
                raise ValueError(f"{name} must be in (0, 100), got {getattr(self, name)!r}")
        for name in ("min_weight", "inside", "max_overlap"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")
        if self.min_heat is not None and not 0 <= self.min_heat < float("inf"):
            raise ValueError(f"min_heat must be a finite number >= 0 or None, got {self.min_heat!r}")
        if isinstance(self.max_frame_windows, bool) or not isinstance(self.max_frame_windows, int) \
                or self.max_frame_windows < 2:
            raise ValueError(f"max_frame_windows must be an integer >= 2, got {self.max_frame_windows!r}")

"""Heat blobs over vehicles side by side split into one box each (:class:`NeighbourSplit`)."""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

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
    max_frame_windows: at most this many windows go into the mean shift in one frame (each
        blob gives at most ``blobsplit.MAX_WINDOWS``, the heaviest blobs first; a blob that
        no longer fits keeps its heat box whole): the split's cost a frame is bounded on a
        frame of many big blobs over dense texture. The annotated clips stay far below it.
    """

    #: the deleted ``min_heat`` (docs/accuracy.md, "Deleted stages"): never written while off,
    #: so the dicts and digests are those of before
    _RETIRED = MappingProxyType({"min_heat": None})
    _OMIT_NONE = ("min_heat",)
    _OMIT_DEFAULT = {"max_frame_windows": 512}

    min_aspect: float = 1.8
    min_weight: float = 0.5
    bandwidth: float = 0.25
    scale_bandwidth: float = 0.3
    inside: float = 0.5
    max_overlap: float = 0.3
    max_frame_windows: int = 512

    def __post_init__(self) -> None:
        for name in ("min_aspect", "bandwidth", "scale_bandwidth"):
            if not 0 < getattr(self, name) < 100:
                raise ValueError(f"{name} must be in (0, 100), got {getattr(self, name)!r}")
        for name in ("min_weight", "inside", "max_overlap"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)!r}")
        if isinstance(self.max_frame_windows, bool) or not isinstance(self.max_frame_windows, int) \
                or self.max_frame_windows < 2:
            raise ValueError(f"max_frame_windows must be an integer >= 2, got {self.max_frame_windows!r}")

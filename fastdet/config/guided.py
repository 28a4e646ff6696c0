"""How video searches the main model's bands between full scans (:class:`GuidedSearch`)."""
from __future__ import annotations

from dataclasses import dataclass

from ._base import Config


@dataclass(frozen=True)
class GuidedSearch(Config):
    """How :class:`~fastdet.VideoDetector` searches the main model's bands between full scans
    (:mod:`fastdet.video.guided`): every window every ``every`` frames, near the tracked
    vehicles and recent positive windows plus a rotating strip in between.

    every: a full scan every this many frames; 1 = every frame (the exact full search).
    margin: around a track's box, this fraction of its width on each side; around a
        positive window, this fraction of the window width.
    memory: positive windows of this many recent frames guide the search.
    scales: a band searches near a track when its window side is within
        ``[scales[0], scales[1]] x`` the track's box height.
    lost_growth: a track lost for ``n`` frames gets ``n x lost_growth x`` its width more margin
        (at most one width more).
    """

    every: int = 5
    margin: float = 0.5
    memory: int = 2
    scales: tuple[float, float] = (0.4, 2.0)
    lost_growth: float = 0.25

    def __post_init__(self) -> None:
        if int(self.every) != self.every or self.every < 1:
            raise ValueError(f"every must be an integer >= 1, got {self.every!r}")
        if self.margin < 0 or self.lost_growth < 0:
            raise ValueError("margin and lost_growth must be >= 0")
        if int(self.memory) != self.memory or self.memory < 1:
            raise ValueError(f"memory must be an integer >= 1, got {self.memory!r}")
        lo, hi = self.scales
        if not 0 < lo <= hi:
            raise ValueError(f"scales must be (low, high) with 0 < low <= high, got {self.scales!r}")
        object.__setattr__(self, "scales", (float(lo), float(hi)))

    @property
    def full(self) -> bool:
        """Every frame is a full scan."""
        return self.every == 1

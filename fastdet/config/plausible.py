"""Returned boxes that cannot be vehicles dropped (:class:`PlausibleConfig`,
:mod:`fastdet.video.plausible`)."""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

from ._base import Config


@dataclass(frozen=True)
class PlausibleConfig(Config):
    """Which of the boxes :class:`~fastdet.VideoDetector` returns are dropped as no vehicle
    (:mod:`fastdet.video.plausible`; measured on every annotated clip: docs/accuracy.md,
    "False alarms on the new cameras").

    max_iou: a box whose IoU with a higher-scored returned box exceeds this is a duplicate and
        is dropped (``None``: never). 0.5: two vehicles that are each at least half in view
        (what a vehicle to find is, data README) overlap by at most IoU 0.5 -- the nearer one
        hides at most half of the farther, so their intersection is at most half of the
        farther one's box and at most all of the nearer one's, which bounds the IoU by 0.5 --
        so a pair above it is one vehicle boxed twice.
    """

    #: the perspective test's fields, deleted (docs/accuracy.md, "Deleted stages"), at their off
    #: values: the dicts written with them still load, the digests as before
    _RETIRED = MappingProxyType({"perspective": False, "min_ratio": 0.45, "max_ratio": 12.0, "slack": 0.05})

    max_iou: float | None = 0.5

    def __post_init__(self) -> None:
        if self.max_iou is not None and not 0 <= self.max_iou <= 1:
            raise ValueError(f"max_iou must be in [0, 1] or None, got {self.max_iou!r}")

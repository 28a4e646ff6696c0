"""Returned boxes that cannot be vehicles dropped (:class:`PlausibleConfig`,
:mod:`fastdet.video.plausible`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

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
    perspective: drop the boxes whose width does not fit how far below the horizon their
        bottom edge stands (off by default; why: docs/accuracy.md).
        On a flat road a vehicle of width ``W`` seen by a camera ``h_c`` above the road has a
        width in pixels of ``(W / h_c)`` x the rows between its bottom edge and the horizon
        (Hoiem, Efros & Hebert, "Putting Objects in Perspective", CVPR 2006); a box is kept
        when some horizon within ``slack`` of the pipeline's gives it a ratio in
        ``[min_ratio, max_ratio]``.
    min_ratio: the narrowest a vehicle can be for how low it stands: the narrowest face of a
        vehicle to find (about 1.4 m, a small car's rear) over the highest dashcam (about
        3 m, a truck cab's windscreen): 0.45. Boxes at the frame's left or right edge are
        not held to it (part of the vehicle is out of view).
    max_ratio: the widest: the longest side of a vehicle (about 12 m, a coach or a semi-trailer
        seen side on) over the lowest camera (about 1 m, a motorcycle's dash): 12. A box whose
        bottom edge is more than ``slack`` above the horizon fails it whatever its width.
    slack: how far (a fraction of the frame height) the horizon may be off: the error the
        search bands are made to survive (:attr:`GeometryConfig.slack
        <fastdet.config.GeometryConfig>`).
    """

    max_iou: float | None = 0.5
    perspective: bool = False
    min_ratio: float = 0.45
    max_ratio: float = 12.0
    slack: float = 0.05

    def __post_init__(self) -> None:
        if self.max_iou is not None and not 0 <= self.max_iou <= 1:
            raise ValueError(f"max_iou must be in [0, 1] or None, got {self.max_iou!r}")
        if not isinstance(self.perspective, bool):
            raise TypeError(f"perspective must be True or False, got {type(self.perspective).__name__}")
        for name in ("min_ratio", "max_ratio"):
            v = getattr(self, name)
            if not (0 < v and math.isfinite(v)):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        if not self.min_ratio < self.max_ratio:
            raise ValueError(f"min_ratio must be below max_ratio, got {self.min_ratio!r}, {self.max_ratio!r}")
        if not 0 <= self.slack < 1:
            raise ValueError(f"slack must be a fraction of the frame height in [0, 1), got {self.slack!r}")

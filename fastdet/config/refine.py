"""Learned box refinement in video (:class:`RefineConfig`) and the random boxes its regressor
is trained on (:class:`JitterConfig`)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

from ._base import Config


@dataclass(frozen=True)
class RefineConfig(Config):
    """How :func:`refine` moves boxes.

    iterations: times the regressor is applied (each from the previous result), >= 1; the
        bundled regressor is fitted for 3 (its one-pass boxes are looser on other cameras).
    max_shift: largest centre move per iteration, as a fraction of the box's width / height.
    max_log_scale: largest ``|log|`` size change per iteration (``log(1.5)``: at most 1.5x
        larger or smaller).
    min_size: boxes narrower or lower than this (pixels) are left as they are.
    parts: refine only boxes whose ``part`` is one of these (``None``: every box; boxes of a
        Detections without ``part`` count as part 0).
    """

    #: the stopping rules' fields, deleted (docs/accuracy.md, "Deleted stages"): never written
    #: while off, so the dicts and digests are those of before
    _RETIRED = MappingProxyType({"min_step": None, "max_total_log_scale": None})
    _OMIT_NONE = ("min_step", "max_total_log_scale")

    iterations: int = 3
    max_shift: float = 0.5
    max_log_scale: float = math.log(1.5)
    min_size: int = 8
    parts: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if self.iterations < 1:
            raise ValueError(f"iterations must be >= 1, got {self.iterations}")
        if not (self.max_shift >= 0 and self.max_log_scale >= 0):
            raise ValueError("max_shift and max_log_scale must be >= 0")
        if self.parts is not None:
            object.__setattr__(self, "parts", tuple(int(p) for p in self.parts))


@dataclass(frozen=True)
class JitterConfig(Config):
    """Random boxes about a vehicle's box (:mod:`fastdet.train.refine`). shift: fraction of the width /
    height; scale: ``(low, high)`` size factors (log-uniform); aspect: ``|log|`` aspect change;
    min_iou: smallest IoU with the vehicle kept; per_box: samples per vehicle box."""

    shift: float = 0.25
    scale: tuple[float, float] = (0.7, 1.4)
    aspect: float = 0.2
    min_iou: float = 0.3
    per_box: int = 16

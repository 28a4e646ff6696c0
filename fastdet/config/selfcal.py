"""The main model's operating point set from each video's own windows (:class:`SelfCalibration`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ._base import Config


@dataclass(frozen=True)
class SelfCalibration(Config):
    """How :class:`~fastdet.VideoDetector` moves the main model's decision values per video,
    with no label (:mod:`fastdet.video.selfcal`): over the full scans of the video's first
    frames, the decision value that a fraction ``rate`` of the scored main-model windows
    exceeds is found, and every later decision value of the main model is lowered by its
    distance to ``level``. So on every video the same fraction of windows reaches ``level``:
    a model (or a camera) whose windows all score higher is made stricter, one whose windows
    score lower more lenient. Every threshold the pipeline applies to a main-model window
    (the search's, the slack rows', the heat map's score range) moves with it, as
    :func:`fastdet.train.blend.offset` moves them; the oncoming model's do not. Off unless
    given to :attr:`PipelineConfig.selfcal <fastdet.config.PipelineConfig>`.

    scans: the full scans the estimate uses: those of the first frames (frames 1,
        1 + ``GuidedSearch.every``, ...; a file's are scored ahead, as its horizon is found;
        a live source's are the run's own first full scans, the offset applies after them).
    rate: the fraction of the scored windows (0..1) whose decision values must reach ``level``
        (0.1: mostly background, since vehicles cover a small part of the windows).
    level: the decision value (of the main model, unshifted) that ``rate`` of the windows
        reaches on a typical camera; the default is the bundled model's on the annotated
        cameras (docs/training.md, "Operating point from the video itself").
    max_shift: the offset is clipped to ``[-max_shift, max_shift]`` decision units.
    """

    scans: int = 5
    rate: float = 0.1
    level: float = -8.3
    max_shift: float = 6.0

    def __post_init__(self) -> None:
        if isinstance(self.scans, bool) or int(self.scans) != self.scans or self.scans < 1:
            raise ValueError(f"scans must be an integer >= 1, got {self.scans!r}")
        if not 0 < self.rate < 1:
            raise ValueError(f"rate must be in (0, 1), got {self.rate!r}")
        if not math.isfinite(self.level):
            raise ValueError(f"level must be finite, got {self.level!r}")
        if not 0 <= self.max_shift < math.inf:
            raise ValueError(f"max_shift must be a finite number >= 0, got {self.max_shift!r}")

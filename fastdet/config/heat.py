"""How the heat map turns positive windows into one box per vehicle (:class:`HeatConfig`),
and the heat map of the oncoming-traffic model (:data:`ONCOMING_HEAT`)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar, Literal

from ._base import Config

#: the most frames a heat map remembers (400 s at 25 fps; the ring and its weights grow with it)
MAX_HEAT_FRAMES = 10_000
#: the coarsest heat-map cell in pixels
MAX_HEAT_CELL = 256

BoxMode = Literal["extent", "mean"]
ScoreKind = Literal["probability", "decision"]


@dataclass(frozen=True)
class HeatConfig(Config):
    """Heat map over recent frames (see :mod:`fastdet.video.heatmap`).

    Each positive window adds heat to the pixels it covers; the heat of a frame is the
    age-weighted **mean** of the last ``n_frames`` per-frame maps (weights ``decay**age``,
    normalised by the weights of the frames seen so far), so ``threshold`` and the box
    scores are in "heat of one frame" units whatever ``n_frames`` and ``decay`` are.

    n_frames: frames remembered (ring buffer length); 1 = single frame.
    decay: weight of a frame ``k`` frames old is ``decay**k`` (1 = equal weights).
        Default 0.8: a car moving across the image leaves a short trail, not a long smear.
    threshold: a pixel belongs to a vehicle blob when its heat is strictly greater than this.
        Default 4: more than one confident window (heat ``w_max`` = 4) on the same pixels,
        frame after frame (docs/accuracy.md).
    single_frame_threshold: ``threshold`` used by :meth:`single_frame` (one image, no
        temporal averaging to suppress false alarms, hence a stricter default: 8).
    score_lo, score_hi: a window's heat is linear in its score, from 1 at ``score_lo`` to
        ``w_max`` at ``score_hi``, clipped to [1, w_max] outside. ``None`` = the default of
        the detector's score kind (:meth:`score_range`): decision values (LinearSVC)
        ``(0.0, 2.0)``, probabilities (logistic regression) ``(0.5, 1.0)``.
    w_max: heat of a window scoring ``score_hi`` or more; one confident window outweighs
        ``w_max - 1`` barely-positive ones at the same place.
    box_mode: how a blob becomes a box. ``'extent'``: as below. ``'mean'``: the
        heat-weighted mean of the boxes of this frame's windows whose centre lies in the blob
        (a box of the windows' own shape, placed where they agree; falls back to
        ``'extent'`` for a blob with no window of this frame).
    extent: a blob's box is the bounding box of its cells with heat >= ``extent`` x the
        blob's peak heat (0 = the whole blob). Square windows that fire a little above,
        below and beside a car make a blob wider and much taller than the car; its
        "width at 40% of the peak" fits the car far better (docs/accuracy.md).
    split_gap: ``0`` (default) = one box per blob. Otherwise a blob is first split by its
        windows of this frame (those whose centre lies in it): sorted by the x of their
        centres, they fall into groups wherever two neighbours are more than ``split_gap``
        x the median window width apart, and each group gives one box (its ``extent`` box
        within the blob, limited to the columns its windows cover). For two cars side by side
        whose windows merge into one blob. The wide-window (oncoming traffic) heat map uses
        0.5: windows whose centres are half a window apart do not see the same car.
    cell: heat-map resolution in pixels; boxes are snapped to this grid (rounded to the
        nearest multiple). Windows start on an 8-px grid at scale 1, so 4 loses nothing
        visible and is 16x cheaper than full resolution.
    min_width, min_height: smallest box kept (px of a frame of ``reference_rows`` rows).
    reference_rows: frame height the pixel sizes ``min_width`` / ``min_height`` are meant for
        (720: a car 40 px wide in a 1280x720 frame is 30 px wide at 960x540, 60 px at
        1920x1080). A :class:`~fastdet.video.heatmap.HeatMap` for frames of ``H`` x ``W`` uses
        :meth:`for_frame` with their short side, ``min(H, W)``, which scales them by
        ``min(H, W) / reference_rows`` (as the search scales its windows:
        :attr:`SearchConfig.reference_shape <fastdet.config.SearchConfig>`); ``None``: pixels
        at every size.
    max_aspect: boxes taller than ``max_aspect * width`` are dropped (no vehicle seen from
        behind or the side is much taller than wide).
    """

    n_frames: int = 8
    decay: float = 0.8
    threshold: float = 4.0
    single_frame_threshold: float = 8.0
    score_lo: float | None = None
    score_hi: float | None = None
    w_max: float = 4.0
    extent: float = 0.4
    box_mode: BoxMode = "extent"
    split_gap: float = 0.0
    cell: int = 4
    min_width: int = 40
    min_height: int = 20
    max_aspect: float = 1.5
    reference_rows: int | None = 720

    #: default ``(score_lo, score_hi)`` by ``Detector.score_kind``
    SCORE_RANGES: ClassVar[dict[str, tuple[float, float]]] = {"decision": (0.0, 2.0), "probability": (0.5, 1.0)}

    def __post_init__(self) -> None:
        if int(self.n_frames) != self.n_frames or self.n_frames < 1:
            raise ValueError("n_frames must be an integer >= 1")
        if self.n_frames > MAX_HEAT_FRAMES:
            raise ValueError(f"n_frames must be at most {MAX_HEAT_FRAMES}, got {self.n_frames}")
        if not 0 < self.decay <= 1:
            raise ValueError("decay must be in (0, 1]")
        for name in ("threshold", "single_frame_threshold"):
            v = getattr(self, name)
            if not v >= 0 or v == float("inf"):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if (self.score_lo is None) != (self.score_hi is None):
            raise ValueError("give both score_lo and score_hi, or neither")
        if self.score_lo is not None and self.score_hi is not None and not self.score_hi > self.score_lo:
            raise ValueError(f"score_hi must exceed score_lo, got {self.score_lo}..{self.score_hi}")
        if not 1 <= self.w_max < float("inf"):
            raise ValueError(f"w_max must be a finite number >= 1, got {self.w_max!r}")
        if not 0 <= self.extent <= 1:
            raise ValueError(f"extent must be in [0, 1], got {self.extent!r}")
        if self.box_mode not in ("extent", "mean"):
            raise ValueError(f"box_mode must be 'extent' or 'mean', got {self.box_mode!r}")
        if not 0 <= self.split_gap < float("inf"):
            raise ValueError(f"split_gap must be a finite number >= 0, got {self.split_gap!r}")
        if self.split_gap > 0 and self.box_mode != "extent":
            raise ValueError("split_gap needs box_mode 'extent'")
        if int(self.cell) != self.cell or not 1 <= self.cell <= MAX_HEAT_CELL:
            raise ValueError(f"cell must be an integer in 1..{MAX_HEAT_CELL}")
        if self.min_width < 0 or self.min_height < 0:
            raise ValueError("min_width and min_height must be >= 0")
        if not self.max_aspect > 0:
            raise ValueError("max_aspect must be > 0")
        if self.reference_rows is not None and (int(self.reference_rows) != self.reference_rows
                                                or self.reference_rows < 1):
            raise ValueError(f"reference_rows must be an integer >= 1 or None, got {self.reference_rows!r}")

    def for_frame(self, frame_rows: int) -> HeatConfig:
        """This config for frames whose short side is ``frame_rows`` px (a landscape frame's
        rows): ``min_width`` / ``min_height`` scaled by ``frame_rows / reference_rows``
        (rounded), ``reference_rows`` = ``None``."""
        if self.reference_rows is None:
            return self
        f = int(frame_rows) / self.reference_rows
        return replace(self, min_width=int(round(self.min_width * f)), min_height=int(round(self.min_height * f)),
                       reference_rows=None)

    def score_range(self, score_kind: str = "decision") -> tuple[float, float]:
        """``(score_lo, score_hi)``: the configured values, or the default for ``score_kind``."""
        if self.score_lo is not None and self.score_hi is not None:
            return float(self.score_lo), float(self.score_hi)
        try:
            return self.SCORE_RANGES[score_kind]
        except KeyError:
            raise ValueError(f"score_kind must be one of {sorted(self.SCORE_RANGES)}, got {score_kind!r}") from None

    def single_frame(self, threshold: float | None = None) -> HeatConfig:
        """This config for one image: ``n_frames=1`` and ``single_frame_threshold`` (or ``threshold``)."""
        t = self.single_frame_threshold if threshold is None else threshold
        return replace(self, n_frames=1, threshold=t)


#: heat map of the oncoming-traffic model's windows (VideoDetector): no memory (the cars it is
#: for cross the view in half a second), blobs split between groups of windows half a window
#: apart (two oncoming cars side by side), a box around the cells with at least 0.3 x the
#: peak heat, wider than tall
ONCOMING_HEAT = HeatConfig(n_frames=1, threshold=8.0, extent=0.3, box_mode="extent", split_gap=0.5, min_height=10,
                           max_aspect=0.8)

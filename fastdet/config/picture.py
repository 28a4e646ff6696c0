"""How a single picture is searched when there is no video to place the search from:
:class:`PictureSearch`.

The video pipeline's bands (:class:`~fastdet.config.SearchConfig`) put each window size where
cars of that size stand below a dashcam's horizon; a photo from any other camera has no such
place. A picture search covers the **whole picture at every scale**: window sizes from
``min_width`` x the picture's width up to ``max_height`` x its height, ``steps`` sizes per
octave, every band spanning every row and column, windows ``cells_per_step`` HOG cells apart.
Positive windows (decision value above ``threshold``) become boxes by greedy non-maximum
suppression (the best window first, every window overlapping a kept one at IoU above
``nms_iou`` dropped).

Then each box is refined by the video's box regressor (``refine``) and looked at again by the
box verifier (``verify``, :mod:`fastdet.detect.verifier`), which keeps the boxes it scores above
its threshold: a cascade, whose first stage (the window model, NMS) keeps every window above
decision value 0 and whose second stage removes most of their false alarms.

Defaults chosen by measurement (docs/benchmarks.md, "Single pictures"; docs/accuracy.md,
"Labelled picture sets" and "The picture search's second stage"): 2 sizes an octave, 2 cells a
step (the 50 ms budget at 1280x720), NMS at IoU 0.3 (a single-frame heat map, deleted, merged
the windows of neighbouring cars and of clutter into large blobs on pictures of other cameras and
scored lower on every labelled picture set), windows above
decision value 0 with the refinement and the verifier (without the verifier, decision value 2
had the best F1 on dawn_fog: ``PictureSearch(verify=False, nms_min_score=2)``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ._base import Config
from .refine import RefineConfig
from .search import SearchBand, SearchConfig


@dataclass(frozen=True)
class PictureSearch(Config):
    """The search of one picture (module docstring).

    min_width: smallest window, a fraction of the picture's width (1/32: the data's smallest
        target; never below two HOG cells).
    max_height: largest window, a fraction of the picture's height (1: as tall as the picture).
    steps: window sizes per octave (each size ``2 ** (1 / steps)`` x the one before).
    cells_per_step: window stride in HOG cells of the scaled band (1 or 2; 2 is 2-4x cheaper).
    threshold: a window is positive when its decision value exceeds this.
    nms_iou: two windows overlapping at more than this IoU see the same vehicle.
    nms_min_score: decision value a window needs to become a box (at least ``threshold``).
    refine: how the learned box regressor moves each box onto its vehicle
        (:class:`~fastdet.config.RefineConfig`, the video's; :mod:`fastdet.video.refine`);
        ``None``: the boxes are the windows as found.
    verify: the box verifier (:mod:`fastdet.detect.verifier`) takes a second look at each
        refined box and keeps those it scores above its threshold, scored by its decision
        value; ``False``: every box the first stage found, scored by its window's decision value.
    """

    min_width: float = 1 / 32
    max_height: float = 1.0
    steps: int = 2
    cells_per_step: int = 2
    threshold: float = 0.0
    nms_iou: float = 0.3
    nms_min_score: float = 0.0
    refine: RefineConfig | None = RefineConfig()
    verify: bool = True

    def __post_init__(self) -> None:
        if self.verify and self.refine is None:
            raise ValueError("verify looks at refined boxes (it was fitted on them): give refine or verify=False")
        if not 0 < self.min_width <= 1:
            raise ValueError(f"min_width must be a fraction of the picture width in (0, 1], got {self.min_width!r}")
        if not 0 < self.max_height <= 1:
            raise ValueError(f"max_height must be a fraction of the picture height in (0, 1], "
                             f"got {self.max_height!r}")
        if self.steps < 1:
            raise ValueError(f"steps must be >= 1, got {self.steps!r}")
        if self.cells_per_step < 1:
            raise ValueError(f"cells_per_step must be >= 1, got {self.cells_per_step!r}")
        if not math.isfinite(self.threshold):
            raise ValueError(f"threshold must be a finite number, got {self.threshold!r}")
        if not 0 < self.nms_iou < 1:
            raise ValueError(f"nms_iou must be in (0, 1), got {self.nms_iou!r}")
        if not math.isfinite(self.nms_min_score):
            raise ValueError(f"nms_min_score must be a finite number, got {self.nms_min_score!r}")

    def scales(self, shape: tuple[int, int], window: int = 64, cell: int = 8) -> tuple[float, ...]:
        """The window scales (window width / ``window`` px) searched in a picture of ``shape =
        (H, W)`` px: from ``max(min_width x W, 2 x cell) / window`` up by ``2 ** (1 / steps)``
        while the window fits ``max_height x H`` (and the picture's width); empty when not even
        the smallest window fits."""
        h, w = (int(v) for v in shape[:2])
        lo = max(self.min_width * w, 2 * cell) / window
        top = min(self.max_height * h, w)
        out = []
        k = 0
        while window * lo * 2 ** (k / self.steps) <= top + 1e-9:
            out.append(lo * 2 ** (k / self.steps))
            k += 1
        return tuple(out)

    def search(self, shape: tuple[int, int], window: int = 64, cell: int = 8) -> SearchConfig:
        """The :class:`SearchConfig` of a picture of ``shape = (H, W)`` px for a model of
        ``window`` px windows and ``cell`` px HOG cells: one band a scale (:meth:`scales`) over
        every row, columns to a whole number of its scaled cells, no window over the edge;
        bands in the picture's own pixels. ``ValueError`` when the picture is smaller than the
        smallest window."""
        h, w = (int(v) for v in shape[:2])
        bands = []
        for s in self.scales((h, w), window, cell):
            px = cell * s
            bands.append(SearchBand(s, 0, h, 0, min(w, int(w // px * px)) or w))
        if not bands:
            n = math.ceil(max(self.min_width * w, 2 * cell))
            raise ValueError(f"a {w}x{h} picture is too small for the picture search: its smallest window "
                             f"({n}x{n} px) does not fit")
        return SearchConfig(bands=tuple(bands), cells_per_step=self.cells_per_step, threshold=self.threshold,
                            reference_shape=None, border=0.0, slack_threshold=None)


#: the default picture search
PICTURE_SEARCH = PictureSearch()
#: the first stage alone (``image --no-refine``): windows above decision value 2 after NMS, as found
#: (without the second stage, 2 had the best F1 on dawn_fog)
FIRST_STAGE_ONLY = PictureSearch(nms_min_score=2.0, refine=None, verify=False)

"""The small-vehicle component: a low-resolution model of distant vehicles (its features
:data:`SMALL_FEATURES`, its search :func:`small_search`, its heat map :data:`SMALL_HEAT`).

A vehicle 40-60 px wide (of 1280) has no fine detail: its picture holds about what a 64x64
crop of the data set holds once shrunk to 32x32. So the model is trained on the data set's
crops downscaled to :data:`SMALL_WINDOW` (``cv2.INTER_AREA``) with HOG on 8-px cells, a coarse
template (Park, Ramanan & Fowlkes, "Multiresolution models for object detection", ECCV 2010),
and scored on the frame at its own resolution (the main model's smallest band is the frame
upsampled 1.33x instead). It searches only a band about the horizon, where vehicles that
small stand (docs/components.md, "Small vehicles: a low-resolution model").
"""
from __future__ import annotations

from .features import FeatureConfig
from .heat import HeatConfig
from .search import REFERENCE_HORIZON, REFERENCE_SHAPE, SearchBand, SearchConfig

#: side of the small model's square windows, in pixels (4 x 4 HOG cells of 8 px)
SMALL_WINDOW = 32
#: the small model's features: the main model's kind (YCrCb, HOG of all three channels, spatial
#: bins, colour histogram) on a 32x32 window; spatial bins 16x16 (the main model's 32x32 on 64)
SMALL_FEATURES = FeatureConfig(window=SMALL_WINDOW, spatial_size=16, orientations=9)
#: window widths of the small search, in units of :data:`SMALL_WINDOW` at the reference frame
#: (1280x720): 40 .. 64 px windows for vehicles about 36 .. 60 px wide, every band shrunk (a
#: scale >= 1 never upsamples a 1280x720 frame)
SMALL_SCALES = (1.25, 1.5, 1.75, 2.0)


def _small_bands(scales: tuple[float, ...] = SMALL_SCALES, above: float = 0.6, below: float = 1.4,
                 slack: float = 0.02) -> tuple[SearchBand, ...]:
    # A vehicle w px wide stands with its bottom about w / 1.2 below the horizon (a car 1.8 m
    # wide, a camera 1.5 m high) and its top a little above or below it: windows of side w from
    # ``above`` x w above the reference horizon to ``below`` x w below it, plus ``slack`` x H
    # on both sides for cameras whose horizon estimate is a little off.
    rows, hz = REFERENCE_SHAPE[0], REFERENCE_HORIZON * REFERENCE_SHAPE[0]
    out = []
    for s in scales:
        w = SMALL_WINDOW * s
        y0 = max(0, int(round(hz - above * w - slack * rows)))
        y1 = min(rows, int(round(hz + below * w + slack * rows)))
        out.append(SearchBand(s, y0, y1))
    return tuple(out)


def small_search() -> SearchConfig:
    """The default search of the small-vehicle component: :data:`SMALL_SCALES` over the whole
    width in a band about the horizon (moving with it), windows one HOG cell apart (a window
    is only four cells wide), positive above decision value 0 (probability 0.5), the bands
    shrunk with ``cv2.INTER_AREA`` as the training crops were."""
    return SearchConfig(bands=_small_bands(), cells_per_step=1, threshold=0.0, shrink="area")


#: default search of the small-vehicle component
SMALL_SEARCH = small_search()
#: the small-vehicle component's heat threshold: half the small vehicles its windows reach pass
#: (the median peak heat of its heat map inside the annotated vehicles under 60 px wide that get
#: any heat, over the five annotated clips: 3.5; docs/components.md states the rule and its
#: leave-one-clip-out values)
SMALL_THRESHOLD = 3.5
#: the second look at the small component's boxes (:class:`fastdet.video.small.MainModelCheck`):
#: a box is kept when the main model gives its square crop a decision value above this, a
#: probability of being a vehicle of at least 1% (log(0.01 / 0.99) = -4.6): it only drops what the
#: main model is sure is no vehicle
SMALL_CHECK = -4.6
#: heat map of the small-vehicle component's windows (:class:`~fastdet.VideoDetector`): its own,
#: apart from the main one (a small model's windows on a big car would stretch its box), the main
#: heat map's memory and window weights, :data:`SMALL_THRESHOLD`, blobs split between groups of
#: windows half a window apart (a small vehicle is about one window: windows whose centres are
#: half a window apart do not see the same one; as the oncoming heat map's, for queues of distant
#: cars); its boxes join the main heat map's where those found nothing (docs/components.md)
SMALL_HEAT = HeatConfig(threshold=SMALL_THRESHOLD, split_gap=0.5)

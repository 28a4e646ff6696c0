"""One linear model's weights laid out for the dense scoring kernel, with its search bands:
the decision values of every window of one band (or of chosen window columns) of a frame.
Used by :class:`~fastdet.detect.detector.Detector`, one per model part."""
from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..config import SearchConfig
from ..features import (
    convert_color,
    hist_bin_shift,
    hog_channels,
    spatial_factor,
    spatial_map,
)
from ..model import Model
from .bands import BandGeometry, PaddedFrame, band_geometry, scaled_band
from .geometry import row_thresholds
from .scoring import dense_scores, hist_weight_integral, weight_table

#: bands whose row thresholds a scorer keeps (more than any search has; bands that move with
#: the picture come and go)
_MAX_CACHED_BANDS = 256


class _Scorer:
    """One linear model's weights laid out for :func:`dense_scores`, with its search bands."""

    def __init__(self, model: Model, search: SearchConfig):
        self.model, self.search = model, search
        cfg = self.config = model.config
        if cfg.spatial_size and cfg.pixels_per_cell % spatial_factor(cfg):
            raise ValueError(f"spatial_size {cfg.spatial_size} needs windows on a grid of "
                             f"{spatial_factor(cfg)} px; cells are {cfg.pixels_per_cell} px")
        w, b = model.folded()
        nch, bx, by = len(cfg.hog_channels), cfg.blocks_x, cfg.blocks_y
        cpb, o = cfg.cells_per_block, cfg.orientations
        self.k = nch * cpb * cpb * o
        # feature order (channel, block row, block col, ...) → rows of blocks, all channels
        self.w_hog = np.ascontiguousarray(
            w[: cfg.n_hog].reshape(nch, by, bx, cpb, cpb, o).transpose(1, 2, 0, 3, 4, 5).reshape(by, bx * self.k))
        pos = cfg.n_hog
        sh, sw = cfg.spatial_shape
        self.w_sp = np.ascontiguousarray(w[pos: pos + cfg.n_spatial].reshape(sh, 3 * sw)) if sh else np.zeros((0, 0))
        pos += cfg.n_spatial
        self.w_hist = np.ascontiguousarray(w[pos:].reshape(3, cfg.hist_bins)) if cfg.hist_bins else None
        self.hist_table = weight_table(self.w_hist, hist_bin_shift(cfg)) if self.w_hist is not None else None
        self.bias = b
        # row_thresholds of the bands met so far, by (band geometry, threshold, slack threshold):
        # a band's rows and thresholds are the same on every frame of a video
        self._thresholds: dict[tuple[BandGeometry, float, float | None], np.ndarray | float] = {}
        # geometries() of the frame sizes and searches met so far
        self._geometries: dict[tuple[tuple[int, ...], SearchConfig], tuple[BandGeometry, ...]] = {}

    def geometries(self, frame_shape: tuple[int, int]) -> list[BandGeometry]:
        """The geometry of every band of the search on a frame of ``frame_shape = (H, W)``, worked
        out once per frame size and search (the same on every frame of a video; a frame asks for
        them several times)."""
        key = (tuple(int(v) for v in frame_shape[:2]), self.search)
        cache = True
        try:
            geos = self._geometries.get(key)
        except TypeError:  # a search of unhashable parts (a study's own): worked out every time
            cache, geos = False, None
        if geos is None:
            search = self.search.for_frame(frame_shape, self.config.win_w, self.config.pixels_per_cell)
            geos = tuple(band_geometry(b, frame_shape, self.config, search.cells_per_step, search.border,
                                       search.border_mode, search.shrink)
                         for b in search.bands)
            if cache:
                if len(self._geometries) >= _MAX_CACHED_BANDS:  # searches given per frame
                    self._geometries.clear()
                self._geometries[key] = geos
        return list(geos)

    def row_thresholds(self, geo: BandGeometry) -> np.ndarray | float:
        """:func:`~fastdet.detect.geometry.row_thresholds` of the band ``geo`` under this
        scorer's search, computed once per band (a read-only ``(geo.ny,)`` array, or a float)."""
        key = (geo, self.search.threshold, self.search.slack_threshold)
        thr = self._thresholds.get(key)
        if thr is None:
            thr = row_thresholds(geo, self.search, self.config)
            if isinstance(thr, np.ndarray):
                thr.setflags(write=False)
            if len(self._thresholds) >= _MAX_CACHED_BANDS:  # bands given per frame (the oncoming search's)
                self._thresholds.clear()
            self._thresholds[key] = thr
        return thr

    @property
    def feature_key(self) -> tuple:
        """What a band's pixels, HOG block map and spatial-bin map depend on besides the band: two
        scorers of equal keys share them on a band (:func:`group_band_scores`); the colour
        histogram weights and the window height are each scorer's own."""
        c = self.config
        return (c.window, c.orientations, c.pixels_per_cell, c.cells_per_block, tuple(c.hog_channels),
                c.color_space, c.spatial_size, spatial_factor(c) if c.spatial_size else 1)

    def band_scores(self, frame: np.ndarray, geo: BandGeometry, timings: dict[str, float] | None,
                    serial: bool = False, spans: Sequence[tuple[int, int]] | None = None,
                    padded: PaddedFrame | None = None) -> np.ndarray:
        """Decision values of the band's windows (``spans``: only the window columns
        ``j0 <= j < j1`` of each ``(j0, j1)``, the others -inf; see :meth:`Detector.detect`;
        ``padded``: the frame's :func:`~fastdet.detect.bands.pad_frame`, if made)."""
        return group_band_scores(frame, [(self, geo)], timings, serial, spans, padded)[0]


def image_key(geo: BandGeometry) -> tuple[Any, ...]:
    """The band's scaled pixels as :func:`~fastdet.detect.bands.scaled_band` cuts them, whatever
    the window height: the geometry's fields but its window rows (``ny``)."""
    return (geo.band, geo.x0, geo.y0, geo.x1, geo.y1, geo.scaled_w, geo.scaled_h, geo.nx, geo.step, geo.pad_left,
            geo.pad_right, geo.border_mode, geo.shrink)


def group_band_scores(frame: np.ndarray, members: Sequence[tuple[_Scorer, BandGeometry]],
                      timings: dict[str, float] | None, serial: bool = False,
                      spans: Sequence[tuple[int, int]] | None = None,
                      padded: PaddedFrame | None = None) -> list[np.ndarray]:
    """Decision values ``(geo.ny, geo.nx) float64`` of the windows of one band for each member
    ``(scorer, geometry)``: scorers of one :attr:`~_Scorer.feature_key` on geometries of one
    :func:`image_key` (a main model and its side-view component on the same search band), so
    the band is cut, resized, colour-converted and its HOG block map and spatial-bin map made
    once for all of them; each scores its windows with its own weights. The values are those
    each scorer gives the band alone (the same arithmetic). ``spans``: as
    :meth:`_Scorer.band_scores`, for every member."""
    lead, geo = members[0]
    if any(sc.feature_key != lead.feature_key or image_key(g) != image_key(geo) for sc, g in members[1:]):
        raise ValueError("group_band_scores: the members must share the band's pixels and features")
    cfg = lead.config
    if spans is not None and not any(min(j1, geo.nx) > max(j0, 0) for j0, j1 in spans):
        return [np.full((g.ny, g.nx), -np.inf) for _, g in members]  # nothing to score: not even the resize
    t0 = time.perf_counter()
    img = convert_color(scaled_band(frame, geo, padded), cfg.color_space)
    t1 = time.perf_counter()
    t_hog = t_score = 0.0
    if spans is None:
        outs = [np.empty((g.ny, g.nx), np.float64) for _, g in members]
        t_hog, t_score = _image_scores(img, geo.step, members, outs, serial)
    else:
        # Every window of a span, scored on a column slice of the scaled band that runs one
        # window step (>= 1 cell) past it on each side where the band goes on: HOG zeroes the
        # gradients of an image's first and last columns, so a window touching the slice's
        # edge would see other values than in the whole band. The slice starts on the
        # window grid, so its windows are the band's own; the margin ones are dropped.
        outs = [np.full((g.ny, g.nx), -np.inf) for _, g in members]
        px = geo.step * cfg.pixels_per_cell  # window step in scaled-band pixels
        for j0, j1 in spans:
            j0, j1 = max(int(j0), 0), min(int(j1), geo.nx)
            if j0 >= j1 or not any(g.ny for _, g in members):
                continue
            a = (j0 - 1) * px if j0 > 0 else 0
            b = min(img.shape[1], (j1 - 1) * px + cfg.win_w + px)
            sub = np.ascontiguousarray(img[:, a:b])
            parts = [np.empty((g.ny, (b - a - cfg.win_w) // px + 1), np.float64) for _, g in members]
            th, ts = _image_scores(sub, geo.step, members, parts, serial)
            t_hog, t_score = t_hog + th, t_score + ts
            for out, part in zip(outs, parts):
                out[:, j0:j1] = part[:, j0 - a // px: j1 - a // px]
    if timings is not None:
        timings["resize_colour"] = timings.get("resize_colour", 0.0) + (t1 - t0)
        timings["hog"] = timings.get("hog", 0.0) + t_hog
        timings["score"] = timings.get("score", 0.0) + t_score
    return outs


def _image_scores(img: np.ndarray, step: int, members: Sequence[tuple[_Scorer, BandGeometry]],
                  outs: Sequence[np.ndarray], serial: bool) -> tuple[float, float]:
    """Decision values of the windows of a scaled, colour-converted band image (``step`` cells
    apart) into each member's ``out (ny, nx)``; returns the seconds of HOG and of scoring."""
    cfg = members[0][0].config
    t1 = time.perf_counter()
    blocks = hog_channels(img, cfg.orientations, cfg.pixels_per_cell, cfg.cells_per_block,
                          channels=list(cfg.hog_channels), exact=False)
    t2 = time.perf_counter()
    if not any(out.size for out in outs):
        return t2 - t1, time.perf_counter() - t2
    rows = blocks.reshape(blocks.shape[0], -1)
    cell = cfg.pixels_per_cell
    if cfg.spatial_size:
        f = spatial_factor(cfg)
        sp = spatial_map(img, f).astype(np.float64)
        sp = sp.reshape(sp.shape[0], -1)
    else:
        f, sp = 1, None
    for (sc, _), out in zip(members, outs):
        if not out.size:
            continue
        c = sc.config
        integ = hist_weight_integral(img, sc.hist_table, cell) if sc.hist_table is not None else None
        dense_scores(rows, sc.w_hog, sc.k, out, step=step, cell=cell, win_h=c.win_h, win_w=c.win_w,
                     bias=sc.bias, spat_rows=sp, w_sp=sc.w_sp if c.spatial_size else None, sp_off=f,
                     integ=integ, hist_step=cell, parallel=not serial)
    return t2 - t1, time.perf_counter() - t2

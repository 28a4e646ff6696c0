"""Search bands from the camera's geometry and the perspective learnt from a video's own
vehicles: what ``geometry_study``, ``placement_study`` and ``horizon_study`` measure (run by
hand). No stage of the pipeline uses it: the ``perspective`` stage that did was deleted
(docs/accuracy.md, "Deleted stages"), and the code moved here from the package
(``fastdet/detect/geometry.py``, ``fastdet/video/perspective.py``,
``fastdet/config/perspective.py``); the pipeline keeps only the slack rows' thresholds,
:func:`fastdet.detect.geometry.row_thresholds`. docs/geometry.md holds what it scored.

*Geometric bands* (:func:`geometric_bands`, :class:`GeometricSearch`): each window size on the
rows where a vehicle of that size can stand.

On a flat road a vehicle seen by a camera at height ``Hc`` above the road stands with its
bottom edge ``dy = f Hc / Z`` pixels below the horizon and is ``w = f Wv / Z`` pixels wide
(``Z`` its distance, ``f`` the focal length in pixels, ``Wv`` its width), so

    w = ratio x dy,        ratio = Wv / Hc

whatever the lens and the resolution (Hoiem, Efros & Hebert, "Putting Objects in
Perspective", CVPR 2006). The horizon row and the ``ratio`` are all a camera needs to say
where vehicles of each width can be. Cameras differ in both: a dashcam behind a car's
windscreen (``Hc`` about 1.2 m) has a ratio near 1.8 for a car, a motorcycle's lower, a
truck's higher camera a smaller one.

A window of side ``L`` pixels fires on vehicles somewhat wider than itself and sits near
their bottom edge; over all the annotated clips the windows the detector fires on a vehicle
with (IoU >= 0.4) have their bottom ``d x L`` below the horizon with ``d x ratio`` within
``reach`` (the detector's property, not the camera's). So for a window
side ``L`` the band holds the windows whose bottom is in

    [horizon + L x reach[0] / ratio_hi - slack x H,  horizon + L x reach[1] / ratio_lo + slack x H]

where ``[ratio_lo, ratio_hi]`` is the ratio's range (the prior's, or around the estimate
from the video's own vehicles, :class:`RatioEstimator`) and ``slack`` the horizon error the
search must survive (a fraction of the frame height ``H``). Each band's windows stay on
the grid they have in the reference search (rows ``y_ref + n x step`` of the reference
band, scaled to the frame), so a band moved by a few rows does not put every window
somewhere else.

All rows here are fractions of the frame height or pixels of the frame searched; window
scales are those of :class:`~fastdet.config.SearchBand` (window side ``64 x scale`` px of
the reference frame, rescaled by ``H / reference H`` to the frame).

*The perspective updater* (:class:`PerspectiveUpdater`): until the video has shown a vehicle,
the main search is a :class:`GeometricSearch` at the prior: the horizon as the rest of the
pipeline has it (the flow estimate, :mod:`fastdet.video.horizon`, or the user's ``--horizon``),
the prior ratio, and a slack of ``slack`` x the frame height above and below every band, so a
horizon that is off by that much still finds the first vehicles. Every frame, the tracked boxes
whose score is at least ``min_score`` feed a :class:`PerspectiveEstimator`; once it has an
estimate (``min_tracks`` tracks of ``min_boxes`` boxes), the bands move to its horizon and
ratio and the slack drops to ``settled_slack``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Literal

import numpy as np

from fastdet.config import CELL, WINDOW, Config, SearchBand, SearchConfig
from fastdet.detections import Detections


@dataclass(frozen=True)
class GeometryConfig(Config):
    """How search bands follow the camera's geometry (:func:`geometric_bands`).

    reference_ratio: the ratio of the camera the reference bands were tuned on (1.9; how it
        was measured: docs/geometry.md).
    ratio: the prior ratio, used until the video's own vehicles give one.
    slack: rows added above and below every band, a fraction of the frame height: the
        horizon error a band survives without losing a window that finds a vehicle.
    """

    reference_ratio: float = 1.9
    ratio: float = 1.9
    slack: float = 0.05

    def __post_init__(self) -> None:
        if not self.ratio > 0 or not self.reference_ratio > 0:
            raise ValueError(f"ratio and reference_ratio must be > 0, got {self.ratio!r}, {self.reference_ratio!r}")
        if not 0 <= self.slack < 1:
            raise ValueError(f"slack must be a fraction of the frame height in [0, 1), got {self.slack!r}")


@dataclass(frozen=True)
class PerspectiveConfig(Config):
    """Settings of :class:`PerspectiveUpdater`: the main search follows the horizon and ratio the
    tracked vehicles show (``geometry_study --joint``; once a stage of the pipeline, deleted:
    docs/accuracy.md, "Deleted stages").

    geometry: the bands' geometry (reference ratio, prior ratio); its ``slack`` is the slack
        until there is an estimate.
    settled_slack: the slack once there is one (fraction of the frame height).
    min_score: the score a tracked box needs to count (the heat map's peak).
    min_boxes, min_tracks, long_track: tracks of at least ``min_boxes`` such boxes, at least
        ``min_tracks`` of them (or one track of ``long_track`` boxes; ``None``: never), before
        there is an estimate.
    sigma_h: how far (fraction of the height) the estimate may pull the horizon from the
        prior without cost (one standard deviation of the prior).
    sigma_ratio: the same for the ratio, in log units.
    residuals: how a box's misfit is measured (:class:`PerspectiveEstimator`):
        ``'log'`` (its log ratio against its track's) or ``'rows'`` (its bottom row against
        the one its width puts it on: steadier near the horizon; docs/geometry.md).
    prior_frames: frames the slack is kept while no estimate comes (``None``: until one
        comes); then the bands stay at the prior without slack (a video that shows too few
        vehicles to say where the road is does not pay for the slack for ever).
    """

    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    settled_slack: float = 0.0
    min_score: float = 10.0
    min_boxes: int = 5
    min_tracks: int = 2
    long_track: int | None = None
    sigma_h: float = 0.04
    sigma_ratio: float = 0.5
    prior_frames: int | None = None
    residuals: Literal["rows", "log"] = "log"

    def __post_init__(self) -> None:
        if self.residuals not in ("rows", "log"):
            raise ValueError(f"residuals must be 'rows' or 'log', got {self.residuals!r}")
        if not 0 <= self.settled_slack < 1:
            raise ValueError(f"settled_slack must be in [0, 1), got {self.settled_slack!r}")
        if self.min_boxes < 1 or self.min_tracks < 1:
            raise ValueError("min_boxes and min_tracks must be >= 1")
        if not self.sigma_h > 0 or not self.sigma_ratio > 0:
            raise ValueError("sigma_h and sigma_ratio must be > 0")
        if self.prior_frames is not None and self.prior_frames < 0:
            raise ValueError(f"prior_frames must be >= 0 or None, got {self.prior_frames!r}")


def window_bottoms(ref_first: float, ref_last: float, ref_horizon: float, horizon: float, stretch: float,
                   slack_rows: float, slack_below_rows: float | None = None) -> tuple[float, float]:
    """Rows ``(first, last)`` (frame pixels) the bottom of a window may be on: the reference
    band's window bottoms ``[ref_first, ref_last]`` (rows of a frame whose horizon is at row
    ``ref_horizon``) at the same distances below the horizon times ``stretch`` (the
    reference ratio over the camera's) from row ``horizon``, widened by ``slack_rows`` above
    and ``slack_below_rows`` below (``None``: ``slack_rows`` on both sides)."""
    below = slack_rows if slack_below_rows is None else slack_below_rows
    return (horizon + (ref_first - ref_horizon) * stretch - slack_rows,
            horizon + (ref_last - ref_horizon) * stretch + below)


def band_on_grid(scale: float, first_bottom: float, last_bottom: float, anchor: float, step: float,
                 rows: int, x_start: int | None = None, x_stop: int | None = None,
                 tail: float = 0.0, window: int = WINDOW) -> SearchBand | None:
    """The band of ``scale`` (frame pixels: window side ``window x scale``) whose windows sit on
    the rows ``anchor + n x step`` (window tops) and have their bottoms in
    ``[first_bottom, last_bottom]`` to half a step, clipped to a frame of ``rows`` rows;
    ``None`` when no window fits. ``tail``: rows the band runs on below its last window
    (HOG sees them: a window on a band's last rows is scored a little differently)."""
    side = float(window) * scale
    n0 = math.ceil((first_bottom - side - anchor) / step - 0.5 - 1e-9)
    n1 = math.floor((last_bottom - side - anchor) / step + 0.5 + 1e-9)
    n0 = max(n0, math.ceil((-0.5 - anchor) / step - 1e-9))  # tops inside the frame (to rounding)
    if n1 < n0:
        return None
    top = anchor + n0 * step
    y0 = min(max(int(round(top)), 0), rows - 1)  # bands start on whole rows: the grid to half a pixel
    n1 = min(n1, n0 + math.floor((rows - side - y0) / step + 1e-9))  # bottoms inside the frame
    if n1 < n0:
        return None
    # one window side and (n1 - n0) steps, and the reference band's rows below its last window
    end = y0 + side + (n1 - n0) * step  # the last window's bottom
    y1 = min(max(int(round(end + tail)), int(math.ceil(end - 1e-6))), rows)
    return SearchBand(scale, y0, y1, x_start, x_stop)


def geometric_bands(frame_shape: tuple[int, int], horizon: float, ratio: float, config: GeometryConfig,
                    reference: SearchConfig, window: int = WINDOW, cell: int = CELL) -> tuple[SearchBand, ...]:
    """The main search's bands for frames of ``frame_shape = (H, W)`` whose horizon is at
    ``horizon x H`` and whose vehicles have the ``ratio`` (module docstring): each band of
    ``reference`` (rescaled to the frame as :meth:`SearchConfig.for_frame` does) searches
    the window bottoms it searches at its ``reference_horizon``, at distances below the
    horizon stretched by ``config.reference_ratio / ratio``, plus a slack above and below (on
    each side the larger of ``config.slack`` and the band's own
    :attr:`~fastdet.config.SearchBand.slack_above` above; a band with slack gets the
    rows it has without it as its ``core``); on the reference band's window grid
    (``window`` / ``cell``: the model's window width and HOG cell, px at scale 1). Bands in
    frame pixels."""
    h, w = (int(v) for v in frame_shape[:2])
    rh, rw = reference.reference_shape if reference.reference_shape is not None else (h, w)
    fy, fx = h / rh, w / rw
    stretch = config.reference_ratio / ratio
    out = []
    for b in reference.bands:
        scale = b.scale * fy
        step = reference.cells_per_step * cell * scale
        side = float(window) * scale
        anchor = b.y_start * fy
        n_ref = max(math.floor(((b.y_stop - b.y_start) * fy - side) / step + 1e-6), 0)
        last_ref = anchor + side + n_ref * step
        up, down = max(config.slack, b.slack_above or 0.0) * h, config.slack * h
        x0 = None if b.x_start is None else min(int(round(b.x_start * fx)), w)
        x1 = None if b.x_stop is None else min(int(round(b.x_stop * fx)), w)
        bands = []
        for above, below in ((up, down), (0.0, 0.0)) if up or down else ((0.0, 0.0),):  # with the slack, its core
            first, last = window_bottoms(anchor + side, last_ref, reference.reference_horizon * h,
                                         horizon * h, stretch, above, below)
            bands.append(band_on_grid(scale, first, last, anchor, step, h, x0, x1,
                                      tail=b.y_stop * fy - last_ref, window=window))
        band = bands[0]
        if band is not None and len(bands) == 2:
            core = bands[1]
            band = replace(band, core=(band.y_start, band.y_start) if core is None else (core.y_start, core.y_stop))
        if band is not None:
            out.append(band)
    if not out:
        raise ValueError(f"the horizon at {horizon:g} of the height leaves no search band in a {w}x{h} frame")
    return tuple(out)


@dataclass(frozen=True)
class GeometricSearch(SearchConfig):
    """A :class:`~fastdet.config.SearchConfig` whose bands come from the camera's geometry:
    :meth:`for_frame` places each of ``geometry.scales`` from the horizon (``horizon``, or
    ``reference_horizon`` when ``None``) and the ``ratio`` (``None``: the prior,
    ``geometry.ratio``) with :func:`geometric_bands`. ``bands`` are the reference search's
    (their rows give each scale's window grid)."""

    geometry: GeometryConfig = field(default_factory=GeometryConfig)
    ratio: float | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.ratio is not None and not self.ratio > 0:
            raise ValueError(f"ratio must be > 0 or None, got {self.ratio!r}")

    def for_frame(self, frame_shape: tuple[int, int], window: int = WINDOW, cell: int = CELL) -> SearchConfig:
        horizon = self.horizon if self.horizon is not None else self.reference_horizon
        ratio = self.ratio if self.ratio is not None else self.geometry.ratio
        bands = geometric_bands(frame_shape, horizon, ratio, self.geometry, self, window, cell)
        kw = {f.name: getattr(self, f.name) for f in fields(SearchConfig)}
        kw.update(bands=bands, reference_shape=None, horizon=None)
        return SearchConfig(**kw)

    @classmethod
    def from_search(cls, search: SearchConfig, geometry: GeometryConfig, ratio: float | None = None) -> GeometricSearch:
        """``search`` (its bands, thresholds, horizon ...) with its bands placed from the geometry."""
        return cls(**{f.name: getattr(search, f.name) for f in fields(SearchConfig)}, geometry=geometry, ratio=ratio)

    def with_ratio(self, ratio: float | None) -> GeometricSearch:
        return replace(self, ratio=ratio)


class RatioEstimator:
    """The camera's ratio (vehicle width / how far its bottom edge is below the horizon) from
    the vehicles a video shows (module docstring).

    Feed each frame's confident boxes with :meth:`update` (``(N, 4)`` x1, y1, x2, y2 frame
    pixels, their track ids, the horizon row as a fraction of the height, the frame height);
    a box counts when its bottom is at least ``min_depth`` of the height below the horizon
    (nearer the horizon a row's error is a large part of the distance). Each track gives the
    median of its boxes' ratios; :attr:`estimate` is the median over the tracks seen with at
    least ``min_boxes`` boxes, once there are ``min_tracks`` of them (else ``None``).
    """

    def __init__(self, min_depth: float = 0.03, min_boxes: int = 5, min_tracks: int = 2) -> None:
        if not 0 < min_depth < 1 or min_boxes < 1 or min_tracks < 1:
            raise ValueError("min_depth must be in (0, 1), min_boxes and min_tracks >= 1")
        self.min_depth, self.min_boxes, self.min_tracks = min_depth, min_boxes, min_tracks
        self._per_track: dict[int, list[float]] = {}

    def update(self, boxes: np.ndarray, ids: np.ndarray, horizon: float, rows: int) -> None:
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        ids = np.asarray(ids).reshape(-1)
        if len(ids) != len(b):
            raise ValueError(f"{len(b)} boxes but {len(ids)} ids")
        depth = b[:, 3] - horizon * rows
        ok = (depth >= self.min_depth * rows) & (ids >= 0)
        for r, i in zip((b[ok, 2] - b[ok, 0]) / depth[ok], ids[ok]):
            self._per_track.setdefault(int(i), []).append(float(r))

    def reset(self) -> None:
        self._per_track.clear()

    @property
    def tracks(self) -> int:
        """Tracks with enough boxes so far."""
        return sum(len(v) >= self.min_boxes for v in self._per_track.values())

    @property
    def estimate(self) -> float | None:
        meds = [float(np.median(v)) for v in self._per_track.values() if len(v) >= self.min_boxes]
        if len(meds) < self.min_tracks:
            return None
        return float(np.median(meds))


class PerspectiveEstimator:
    """The horizon and the ratio together from the vehicles a video shows (Hoiem, Efros &
    Hebert's joint inference, by grid search): the horizon row ``h`` and ratio ``k`` that
    best explain the confident boxes (``w = k x (bottom - h)``), pulled towards the prior
    horizon ``h0`` (the flow estimate or the user's) and the prior ratio.

    For each candidate ``h`` (``h0 +- reach`` in steps of ``grid``, fractions of the height)
    each track (one vehicle, one width) gets its own ratio ``k_i``, and the cost is, per
    track, the mean over its boxes of ``min(r^2, clip^2)`` plus ``min((m / sigma_r)^2,
    clip^2)``, ``m`` the track's log ratio less the common one (the median over the tracks:
    vehicles differ in width), plus ``((h - h0) / sigma_h)^2`` and ``(log(k / ratio0) /
    sigma_k)^2``. ``residuals`` says what ``r`` is:

    - ``'rows'``: a box's bottom row less the one its width puts it on,
      ``bottom - h - w / k_i`` (``k_i`` by weighted least squares over the track's boxes; a
      track whose boxes stand above ``h`` fits nowhere), over ``sigma_row + sigma_row_w x w``
      (a box's bottom is known to a few pixels plus a share of its size). A box near the
      horizon says little about the ratio and is weighted as such.
    - ``'log'`` (default): its log ratio ``log(w / (bottom - h))`` less the track's median, over
      ``sigma_box``; a track whose boxes are mostly not below ``h`` counts ``clip^2``. Near
      the horizon a row's error is a large share of ``bottom - h``, so short tracks there
      can pull ``h`` anywhere (docs/geometry.md, "Horizon and ratio together").

    :meth:`estimate` is ``(h, k)`` of the lowest cost once ``min_tracks`` tracks have
    ``min_boxes`` boxes each (or, with ``long_track`` set, one track has that many boxes),
    else ``None``. One vehicle at one depth says little about the horizon, so by default one
    track is never enough.
    """

    def __init__(self, min_boxes: int = 5, min_tracks: int = 2, long_track: int | None = None, reach: float = 0.08,
                 grid: float = 0.0025,
                 sigma_h: float = 0.04, sigma_k: float = 0.5, sigma_r: float = 0.15, sigma_box: float = 0.05,
                 clip: float = 3.0, residuals: str = "log", sigma_row: float = 0.003,
                 sigma_row_w: float = 0.02) -> None:
        if residuals not in ("rows", "log"):
            raise ValueError(f"residuals must be 'rows' or 'log', got {residuals!r}")
        self.min_boxes, self.min_tracks, self.long_track = min_boxes, min_tracks, long_track
        self.reach, self.grid, self.sigma_h, self.sigma_k, self.sigma_r, self.clip = reach, grid, sigma_h, sigma_k, \
            sigma_r, clip
        self.sigma_box = sigma_box
        self.residuals, self.sigma_row, self.sigma_row_w = residuals, sigma_row, sigma_row_w
        self._per_track: dict[int, list[tuple[float, float]]] = {}

    def update(self, boxes: np.ndarray, ids: np.ndarray, rows: int) -> None:
        """Add confident boxes (``(N, 4)`` frame pixels) with their track ids (``-1``: skipped)."""
        b = np.asarray(boxes, np.float64).reshape(-1, 4)
        ids = np.asarray(ids).reshape(-1)
        if len(ids) != len(b):
            raise ValueError(f"{len(b)} boxes but {len(ids)} ids")
        for (x1, _, x2, y2), i in zip(b, ids):
            if i >= 0:
                self._per_track.setdefault(int(i), []).append((y2 / rows, (x2 - x1) / rows))

    def reset(self) -> None:
        self._per_track.clear()

    def estimate(self, h0: float, ratio0: float) -> tuple[float, float] | None:
        tracks = [np.asarray(v) for v in self._per_track.values() if len(v) >= self.min_boxes]
        long_enough = self.long_track is not None and any(len(t) >= self.long_track for t in tracks)
        if len(tracks) < self.min_tracks and not long_enough:
            return None
        best: tuple[float, float, float] | None = None
        for h in np.arange(h0 - self.reach, h0 + self.reach + 1e-9, self.grid):
            if self.residuals == "rows":
                fit, logk = self._row_fit(tracks, float(h))
                cost = fit + ((h - h0) / self.sigma_h) ** 2 + ((logk - math.log(ratio0)) / self.sigma_k) ** 2
                if best is None or cost < best[0]:
                    best = (cost, float(h), math.exp(logk))
                continue
            logs, bad = [], 0
            for t in tracks:
                depth = t[:, 0] - h
                ok = depth > 1e-3
                if ok.sum() * 2 < len(t):
                    bad += 1
                    continue
                logs.append(np.log(t[ok, 1] / depth[ok]))
            if not logs:
                continue
            meds = np.array([np.median(v) for v in logs])
            logk = float(np.median(meds))
            # one vehicle keeps its width: its boxes' ratios agree (to sigma_box) only at the right
            # horizon; vehicles differ in width (sigma_r) around the common ratio
            within = sum(float(np.minimum(((v - m) / self.sigma_box) ** 2, self.clip ** 2).mean())
                         for v, m in zip(logs, meds))
            fit = within + float(np.minimum(((meds - logk) / self.sigma_r) ** 2, self.clip ** 2).sum())
            cost = fit + bad * self.clip ** 2 \
                + ((h - h0) / self.sigma_h) ** 2 + ((logk - math.log(ratio0)) / self.sigma_k) ** 2
            if best is None or cost < best[0]:
                best = (cost, float(h), math.exp(logk))
        return None if best is None else (best[1], best[2])

    def _row_fit(self, tracks: list[np.ndarray], h: float) -> tuple[float, float]:
        """``(cost of the tracks, common log ratio)`` at horizon ``h`` with row residuals (class docstring)."""
        fit, logks = 0.0, []
        for t in tracks:
            y, w = t[:, 0], t[:, 1]
            sig = self.sigma_row + self.sigma_row_w * w
            # rows below the horizon per unit of width (1 / k_i), weighted least squares; a track
            # above h gets a tiny one, so its boxes' residuals are their whole height above h
            c = max(float(np.sum(w * (y - h) / sig ** 2) / np.sum(w * w / sig ** 2)), 1e-3)
            r = (y - h - c * w) / sig
            fit += float(np.minimum(r ** 2, self.clip ** 2).mean())
            logks.append(-math.log(c))
        lk = np.asarray(logks)
        logk = float(np.median(lk))
        return fit + float(np.minimum(((lk - logk) / self.sigma_r) ** 2, self.clip ** 2).sum()), logk


class PerspectiveUpdater:
    """Moves a :class:`fastdet.Detector`'s main search with the perspective the video's
    tracked vehicles show (module docstring).

    :meth:`start` once before the first frame (after the horizon was primed; :meth:`update`
    calls it if not); :meth:`update` after each frame's tracking with its tracked boxes. A cut
    changes nothing (the camera stays: the estimate is kept).
    """

    def __init__(self, detector, config: PerspectiveConfig | None = None) -> None:
        self.detector = detector
        self.config = config if config is not None else PerspectiveConfig()
        c = self.config
        self.estimator = PerspectiveEstimator(min_boxes=c.min_boxes, min_tracks=c.min_tracks, long_track=c.long_track,
                                              sigma_h=c.sigma_h, sigma_k=c.sigma_ratio, residuals=c.residuals)
        self.prior: float | None = None  # the horizon before the vehicles had their say
        self.estimate: tuple[float, float] | None = None
        self._applied: float | None = None  # the horizon this updater last gave the search
        self.frames = 0

    def _search(self) -> SearchConfig:
        return self.detector.scorers[0].search

    def _set_search(self, search: SearchConfig) -> None:
        self.detector.scorers[0].search = search

    def start(self) -> None:
        """Make the main search geometric, at the prior (the detector's horizon as it is now)."""
        s = self._search()
        if not isinstance(s, GeometricSearch):
            s = GeometricSearch.from_search(s, self.config.geometry)
            self._set_search(s)
        self.prior = self._horizon(s)
        self._applied = s.horizon

    @staticmethod
    def _horizon(s: SearchConfig) -> float:
        return s.horizon if s.horizon is not None else s.reference_horizon

    def update(self, boxes: Detections, rows: int) -> None:
        """One frame's tracked boxes (``ids`` set) of a frame of ``rows`` rows."""
        if self.prior is None:
            self.start()
        self.frames += 1
        s = self._search()
        limit = self.config.prior_frames
        if self.estimate is None and limit is not None and self.frames > limit \
                and s.geometry.slack != self.config.settled_slack:  # type: ignore[attr-defined]
            s = replace(s, geometry=replace(self.config.geometry, slack=self.config.settled_slack))
            self._set_search(s)
        if s.horizon != self._applied:  # the horizon estimate from the flow moved it: the new prior
            self.prior, self._applied = self._horizon(s), s.horizon
            if self.estimate is not None:
                self._apply()
        if boxes.ids is None or not len(boxes):
            return
        keep = boxes.scores >= self.config.min_score
        if not keep.any():
            return
        self.estimator.update(boxes.boxes[keep], boxes.ids[keep], rows)
        assert self.prior is not None
        est = self.estimator.estimate(self.prior, self.config.geometry.ratio)
        if est is None:
            return
        self.estimate = est
        self._apply()

    def _apply(self) -> None:
        assert self.estimate is not None
        h = float(np.clip(self.estimate[0], 0.0, 1.0))
        geometry = replace(self.config.geometry, slack=self.config.settled_slack)
        self._set_search(replace(self._search(), horizon=h, ratio=self.estimate[1], geometry=geometry))
        self._applied = h


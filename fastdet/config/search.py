"""Where to search: :class:`SearchBand`, :class:`SearchConfig`, the default bands of the main
model and the oncoming-traffic model's search (:func:`oncoming_search`), which depends on the
side of the road traffic drives on (:data:`TRAFFIC_SIDES`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Literal

from ._base import Config
from .features import CELL, WINDOW

#: the side of the road traffic drives on: ``'right'`` (oncoming cars on the left of the
#: view), ``'left'`` (the UK, Japan, India, Australia ...) or ``'both'`` (search the whole width)
Traffic = Literal["right", "left", "both"]
TRAFFIC_SIDES: tuple[str, ...] = ("right", "left", "both")


def check_traffic(traffic: str) -> str:
    """``traffic`` if it is one of :data:`TRAFFIC_SIDES`, else ``ValueError``."""
    if traffic not in TRAFFIC_SIDES:
        raise ValueError(f"traffic must be 'right', 'left' or 'both', got {traffic!r}")
    return traffic


@dataclass(frozen=True)
class SearchBand(Config):
    """One search band: windows of ``scale x`` the model's window width (64 px by default) in
    frame rows [y_start, y_stop)
    and columns [x_start, x_stop) (``None`` = frame edge).

    slack_above: rows, a fraction of the frame height, the band also searches above
        ``[y_start, y_stop)`` once placed at the frame's horizon (:meth:`SearchConfig.for_frame`:
        the nearest whole number of the band's window steps), for a horizon estimate that is
        too low in the picture by up to that much; a window reaching into those rows is
        positive only above :attr:`SearchConfig.slack_threshold` (on those rows no vehicle of
        the window's size stands when the horizon is right, so what fires there is mostly
        clutter). ``None``: no slack. (Slack below the band was a field too, deleted:
        docs/accuracy.md, "Deleted stages".)
    core: set by :meth:`SearchConfig.for_frame` on a band with slack: the frame rows
        ``[start, stop)`` of the band without its slack (a window inside them needs only the
        search's ``threshold``). ``None``: the whole band is its core.
    """

    #: left out of :meth:`to_dict` while ``None`` (a band written before they existed is the same dict)
    _OMIT_NONE = ("slack_above", "slack_below", "core")
    #: the deleted slack below the band, never written while off (``None``): dicts and digests as before
    _RETIRED = MappingProxyType({"slack_below": None})

    scale: float
    y_start: int
    y_stop: int
    x_start: int | None = None
    x_stop: int | None = None
    slack_above: float | None = None
    core: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        if not self.scale > 0:
            raise ValueError(f"scale must be > 0, got {self.scale}")
        if self.y_stop <= self.y_start:
            raise ValueError(f"y_stop must exceed y_start, got {self.y_start}..{self.y_stop}")
        if self.x_start is not None and self.x_stop is not None and self.x_stop <= self.x_start:
            raise ValueError(f"x_stop must exceed x_start, got {self.x_start}..{self.x_stop}")
        v = self.slack_above
        if v is not None and not 0 <= v < 1:
            raise ValueError(f"slack_above must be a fraction of the frame height in [0, 1) or None, got {v!r}")
        if self.core is not None:
            core = tuple(int(v) for v in self.core)
            if len(core) != 2 or core[0] > core[1]:
                raise ValueError(f"core must be (start, stop) rows with start <= stop, got {self.core!r}")
            object.__setattr__(self, "core", core)

    @property
    def has_slack(self) -> bool:
        """Whether the band searches rows beyond its own (:attr:`slack_above`)."""
        return bool(self.slack_above)


#: rows (fraction of the frame height) the default bands also search above their rows, for a
#: horizon estimate that is too low in the picture (:attr:`SearchBand.slack_above`; not the
#: 48-px band, whose upsampled rows cost the most and whose windows find few vehicles; not
#: below: there the larger windows fire on the road; docs/geometry.md)
BAND_SLACK = 0.03
#: decision value a window in a band's slack rows must exceed (probability 0.9 for the
#: logistic-regression models): there the main model's barely-positive windows are clutter
SLACK_THRESHOLD = 2.2


def _default_bands(slack: float | None = BAND_SLACK) -> tuple[SearchBand, ...]:
    # Each window size where cars of that size stand: all bands start 21 px above the horizon
    # (421 px, SearchConfig.reference_horizon) and reach 1.3-1.5 windows below it; 48-px
    # windows (scale 0.75, the band upsampled before HOG) for the 45-70 px cars of a wider
    # lens, a far lane or the other carriageway, near the horizon only, across the whole width.
    # Every band but the 48-px one with ``slack`` above it, for a horizon estimate that is too low.
    return (
        SearchBand(0.75, 400, 460),
        SearchBand(1.0, 400, 496, slack_above=slack),
        SearchBand(1.25, 400, 528, slack_above=slack),
        SearchBand(1.5, 400, 560, slack_above=slack),
        SearchBand(2.0, 400, 592, slack_above=slack),
        SearchBand(2.5, 400, 656, slack_above=slack),
        SearchBand(3.0, 400, 656, slack_above=slack),
    )


#: horizon row of the frames the default bands are written for (the Udacity clips, 1280x720),
#: a fraction of the frame height: 421 px, the median focus of expansion of their optical flow
#: (:mod:`fastdet.video.horizon`; their lane lines meet at about 419 px)
REFERENCE_HORIZON = 0.585
#: ``(H, W)`` of the frames the default bands are written for
REFERENCE_SHAPE = (720, 1280)


@dataclass(frozen=True)
class SearchConfig(Config):
    """Where and how densely to search.

    bands: the search bands.
    cells_per_step: window stride in HOG cells (of the scaled band).
    threshold: a window is positive when its decision value exceeds this.
    reference_shape: ``(H, W)`` of the frames the bands are written for. A frame of another
        size gets the bands rescaled (:meth:`for_frame`): columns by ``W / reference W``, window
        scales and rows by the ratio of the short sides, ``min(H, W) / min(reference H, W)``
        (a landscape frame: ``H / reference H``; a phone filming upright, whose lens gives a
        vehicle the size it has in the same frames held sideways: ``W / reference H``), the rows
        placed about the horizon (below). ``None``: the bands are used as given, in pixels.
    reference_horizon: the horizon row of those frames, a fraction of their height.
    horizon: the horizon row of the frames searched, a fraction of their height (0 = top),
        or ``None`` for "where the reference frames have it". :meth:`for_frame` moves every
        band after rescaling so that its rows lie about ``horizon x H`` as the reference's lie
        about theirs (a landscape frame: by ``(horizon - reference_horizon) x H``), so each window
        size is searched at the same distance from the horizon, where cars of that size are
        (a car's size and how far below the horizon it stands both scale with 1 / its
        distance, whatever the lens). Each band moves by a whole number of its window steps
        (``cells_per_step x cell x scale`` rows; the nearest to that shift), so its windows sit
        on the grid they have at the reference horizon: a shift of a few rows would put every
        window somewhere else (docs/accuracy.md). Bands are clipped to the frame; a band the clip
        leaves lower than its window (``window x scale`` rows) is dropped. A band with slack
        gets its slack rows added on its grid and its rows without them as its ``core``.
    slack_threshold: the decision value a window must exceed in a band's slack rows
        (:attr:`SearchBand.slack_above`, placed by
        :meth:`for_frame`; ``None``: ``threshold`` there too).
    border: windows may hang this fraction of their width over the left / right frame edge
        (bands whose ``x_start`` / ``x_stop`` is ``None``), so a car cut by the border can fill
        one; the columns past the edge are filled as ``border_mode`` says (``'reflect'``:
        the frame mirrored at its edge, ``'replicate'``: its edge column repeated) and the
        boxes clipped to the frame (:mod:`fastdet.detect.bands`). ``0``: windows stay inside.
    shrink: how a band is shrunk to its windows' scale (scale > 1): ``'linear'`` (default:
        ``cv2.INTER_LINEAR``, what the main model's bands have always used) or ``'area'``
        (``cv2.INTER_AREA``: the mean of the pixels each scaled pixel covers, as a model trained
        on crops shrunk with ``INTER_AREA`` saw them; the deleted small-vehicle component's). A band
        enlarged (scale < 1) is always ``INTER_LINEAR``.
    """

    bands: tuple[SearchBand, ...] = field(default_factory=_default_bands)
    cells_per_step: int = 2
    threshold: float = 0.0
    reference_shape: tuple[int, int] | None = REFERENCE_SHAPE
    reference_horizon: float = REFERENCE_HORIZON
    horizon: float | None = None
    border: float = 0.5
    border_mode: Literal["reflect", "replicate"] = "replicate"
    slack_threshold: float | None = SLACK_THRESHOLD
    shrink: Literal["linear", "area"] = "linear"

    #: the deleted rounding rule of the slack (docs/accuracy.md, "Deleted stages"): never written
    #: while off (``None``), so the dicts and digests are those of before
    _RETIRED = MappingProxyType({"slack_steps": None})
    _OMIT_NONE = ("slack_steps",)

    def for_frame(self, frame_shape: tuple[int, int], window: int = WINDOW, cell: int = CELL) -> SearchConfig:
        """This config with its bands rescaled (and moved to ``horizon``) for frames of
        ``frame_shape = (H, W)``: bands in that frame's pixels (``reference_shape`` and
        ``horizon`` ``None``). ``window`` / ``cell``: the model's window width and HOG cell
        in pixels at scale 1 (:attr:`FeatureConfig.win_w`, :attr:`FeatureConfig.pixels_per_cell`)."""
        h, w = (int(v) for v in frame_shape[:2])
        moved = self.horizon is not None and self.horizon != self.reference_horizon
        slack = any(b.has_slack for b in self.bands)
        if not moved and not slack and (self.reference_shape is None or (h, w) == tuple(self.reference_shape)):
            return self
        rh, rw = self.reference_shape if self.reference_shape is not None else (h, w)
        # sizes -- window scales, rows about the horizon -- go with the frame's short side: the rows
        # of the reference-shaped frame of that short side (a landscape frame: its own height; a
        # phone held upright: the rows its frames have held sideways, the same lens)
        hs = min(h, w) * rh / min(rh, rw)
        fy, fx = hs / rh, w / rw
        # the horizon's row less the row the rescaled bands have it at (a landscape frame at the
        # reference horizon: 0)
        hz = self.horizon if moved and self.horizon is not None else self.reference_horizon
        dy = (hz - self.reference_horizon) * h + self.reference_horizon * (h - hs)

        def col(v: int | None) -> int | None:
            return None if v is None else min(int(round(v * fx)), w)

        bands = []
        for b in self.bands:
            step = self.cells_per_step * cell * b.scale * fy  # rows between window positions
            d = round(dy / step) * step  # whole steps: the windows stay on the reference's grid
            a, z = int(round(b.y_start * fy + d)), int(round(b.y_stop * fy + d))
            core_a, core_z = a, z
            if b.has_slack:  # whole steps more: the windows stay on the grid
                # the nearest number of steps (a band whose step is more than twice its slack gets none)
                up = round((b.slack_above or 0.0) * hs / step) * step
                a = int(round(b.y_start * fy + d - up))
            y0, y1 = max(a, 0), min(z, h)
            if y1 > y0 and ((y0, y1) == (a, z) or y1 - y0 >= window * b.scale * fy):
                c0 = min(max(core_a, y0), y1)
                core = (c0, max(min(core_z, y1), c0)) if b.has_slack else None
                bands.append(SearchBand(b.scale * fy, y0, y1, col(b.x_start), col(b.x_stop), core=core))
        if not bands:
            where = f"the horizon at {self.horizon:g} of the height" if moved else "the frame size"
            raise ValueError(f"{where} leaves no search band in a {w}x{h} frame")
        return replace(self, bands=tuple(bands), reference_shape=None, horizon=None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "bands", tuple(self.bands))
        if not self.bands:
            raise ValueError("a SearchConfig needs at least one band")
        if self.cells_per_step < 1:
            raise ValueError("cells_per_step must be >= 1")
        if self.reference_shape is not None:
            rs = tuple(int(v) for v in self.reference_shape)
            if len(rs) != 2 or min(rs) < 1:
                raise ValueError(f"reference_shape must be (H, W) or None, got {self.reference_shape!r}")
            object.__setattr__(self, "reference_shape", rs)
        if not 0 <= self.border <= 1:
            raise ValueError(f"border must be a fraction of the window width in [0, 1], got {self.border!r}")
        if self.border_mode not in ("reflect", "replicate"):
            raise ValueError(f"border_mode must be 'reflect' or 'replicate', got {self.border_mode!r}")
        if self.slack_threshold is not None and not math.isfinite(self.slack_threshold):
            raise ValueError(f"slack_threshold must be a finite number or None, got {self.slack_threshold!r}")
        if self.shrink not in ("linear", "area"):
            raise ValueError(f"shrink must be 'linear' or 'area', got {self.shrink!r}")
        for name in ("reference_horizon", "horizon"):
            v = getattr(self, name)
            if v is not None and not 0 <= v <= 1:
                raise ValueError(f"{name} must be a fraction of the frame height in [0, 1], got {v!r}")




#: fraction of the reference width the oncoming search covers on the oncoming side of the
#: view (704 of 1280 columns): the oncoming lanes and the median, not the own carriageway
ONCOMING_WIDTH = 0.55
#: scales of the oncoming model's bands: 64x24 windows 40..80 px wide, the oncoming cars seen
#: just above the median
ONCOMING_SCALES = (0.625, 0.75, 0.875, 1.0, 1.25)


def _oncoming_bands(traffic: str = "right") -> tuple[SearchBand, ...]:
    # Columns 0..704 of 1280 where traffic drives on the right (oncoming traffic is on the left
    # of the view), 576..1280 where it drives on the left, or all. Each band is a whole number
    # of its CELL * scale px cells wide, so that the narrowed bands of fastdet.video.motion
    # resample exactly as the full band does.
    width = REFERENCE_SHAPE[1]

    def cols(s: float) -> tuple[int, int]:
        cell = CELL * s
        if traffic == "both":
            return 0, int(width // cell * cell)
        n = int(round(ONCOMING_WIDTH * width) // cell * cell)
        return (0, n) if traffic == "right" else (width - n, width)

    return tuple(SearchBand(s, 400, 400 + int(WINDOW * s) + 24, *cols(s)) for s in ONCOMING_SCALES)


def oncoming_search(traffic: Traffic = "right") -> SearchConfig:
    """The default search of the oncoming-traffic (wide-window) model for roads where traffic
    drives on the ``'right'`` (oncoming cars on the left of the view: the default,
    :data:`ONCOMING_SEARCH`), on the ``'left'`` (the columns mirrored) or ``'both'`` (the whole
    width, about 15% more CPU per frame on footage whose roadside moves fast; docs/accuracy.md).
    Give it as ``Detector(oncoming_search=...)``. (Slack below its bands, for a horizon
    estimate too high in the picture, was an option: it lost boston_street at the estimate and
    was deleted; docs/accuracy.md, "Deleted stages".)"""
    check_traffic(traffic)
    return SearchConfig(bands=_oncoming_bands(traffic), cells_per_step=1, threshold=1.0)


#: default search of the oncoming-traffic model: small scales near the horizon on the left of
#: the view, where oncoming cars half hidden behind the median barrier are seen where traffic
#: drives on the right (:func:`oncoming_search` for the other side).
#: :class:`~fastdet.VideoDetector` narrows it each frame to where the picture moves
#: (:class:`~fastdet.config.MotionGate`).
ONCOMING_SEARCH = oncoming_search("right")

#: window widths of the large-vehicle search, in units of the main model's window (64 px) at
#: the reference frame: 240 .. 448 px of 1280, past the main search's largest (192 px)
LARGE_SCALES = (3.75, 4.5, 5.5, 7.0)
#: decision value a window of the large-vehicle search must exceed (probability 0.982): at the
#: main search's 0 its windows fire on the cars smaller than themselves and on clutter
LARGE_THRESHOLD = 4.0


def _large_bands(scales: tuple[float, ...] = LARGE_SCALES, above: float = 0.5,
                 below: float = 1.2) -> tuple[SearchBand, ...]:
    # A near vehicle w px wide stands with its bottom 0.4..1 w below the horizon (width over
    # camera height 1..2.5: cars at an angle, SUVs, vans) and its top up to half its width
    # above it (taller than the camera is high): windows of side w from ``above`` x w above the
    # reference horizon to ``below`` x w below it, clipped to the frame, at least one window tall.
    rows, hz = REFERENCE_SHAPE[0], REFERENCE_HORIZON * REFERENCE_SHAPE[0]
    out = []
    for s in scales:
        w = WINDOW * s
        y1 = min(rows, int(round(hz + below * w)))
        y0 = max(0, min(int(round(hz - above * w)), y1 - int(-(-w // 1))))
        out.append(SearchBand(s, y0, y1))
    return tuple(out)


def large_search() -> SearchConfig:
    """A search of the main model for large and near vehicles (:data:`LARGE_SCALES`, windows
    240-448 px wide at 1280x720, over the whole width and past its edges as the main search's,
    positive above :data:`LARGE_THRESHOLD`). **Not part of the default search**: its windows
    need a heat map of their own whose boxes join the main ones where those found nothing, as
    a component's (docs/geometry.md, "Large and near vehicles"); :class:`fastdet.Detector`
    ``search=LARGE_SEARCH`` runs it alone."""
    return SearchConfig(bands=_large_bands(), threshold=LARGE_THRESHOLD)


#: the large-vehicle search of the main model (:func:`large_search`)
LARGE_SEARCH = large_search()

"""Frozen configuration dataclasses: what features a model uses (:class:`FeatureConfig`), where
to search (:class:`SearchBand`, :class:`SearchConfig`), how the heat map turns windows into
boxes (:class:`HeatConfig`), how motion gates the wide model (:class:`MotionGate`), how
the tracker gives boxes ids (:class:`TrackerConfig`) and how video searches between full
scans (:class:`GuidedSearch`).

All are plain frozen values (hashable, comparable); the ones with ``to_dict`` /
``from_dict`` (:class:`FeatureConfig`, :class:`HeatConfig`, :class:`MotionGate` ...) round-trip
through JSON, so a model file can record its :class:`FeatureConfig` and loading can check it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Literal

ColorSpace = Literal["RGB", "HSV", "HLS", "LUV", "YCrCb", "YUV"]
COLOR_SPACES: tuple[str, ...] = ("RGB", "HSV", "HLS", "LUV", "YCrCb", "YUV")
BoxMode = Literal["extent", "mean"]
ScoreKind = Literal["probability", "decision"]


def _from_dict(cls, d: dict[str, Any]):
    """``cls(**d)`` for a config dataclass, refusing keys that are not its fields."""
    unknown = set(d) - {f.name for f in fields(cls)}
    if unknown:
        raise ValueError(f"unknown {cls.__name__} fields: {sorted(unknown)}")
    return cls(**d)


@dataclass(frozen=True)
class FeatureConfig:
    """Features of one 64x64 window.

    color_space: colour space the features are computed in (input is BGR uint8).
    hog_channels: channels of that colour space to take HOG of, e.g. ``(0, 1, 2)``.
    orientations, pixels_per_cell, cells_per_block: HOG parameters (square cells/blocks,
        L2-Hys block norm, as ``skimage.feature.hog``).
    spatial_size: side of the spatial-bin image (window resized to it with
        ``cv2.INTER_LINEAR``), 0 to leave the spatial features out.
    hist_bins: bins per channel of the colour histogram over [0, 256), 0 to leave it out.
    window: width of the window in pixels (and its height, unless ``window_height`` is set).
    window_height: height of the window in pixels for a window wider than tall (a model of
        the middle rows of vehicles, for cars half hidden behind a barrier); ``None`` =
        square. Spatial bins shrink both sides by the same factor ``window // spatial_size``.
    """

    color_space: ColorSpace = "YCrCb"
    hog_channels: tuple[int, ...] = (0, 1, 2)
    orientations: int = 16
    pixels_per_cell: int = 8
    cells_per_block: int = 2
    spatial_size: int = 32
    hist_bins: int = 32
    window: int = 64
    window_height: int | None = None

    def __post_init__(self) -> None:
        if self.color_space not in COLOR_SPACES:
            raise ValueError(f"color_space must be one of {COLOR_SPACES}, got {self.color_space!r}")
        chans = self.hog_channels
        if isinstance(chans, str):
            if chans.upper() != "ALL":
                raise ValueError(f"hog_channels must be a list of 0..2 or 'ALL', got {chans!r}")
            chans = (0, 1, 2)
        chans = tuple(int(c) for c in chans)
        if not chans or any(c not in (0, 1, 2) for c in chans) or len(set(chans)) != len(chans):
            raise ValueError(f"hog_channels must be distinct channels in 0..2, got {self.hog_channels!r}")
        object.__setattr__(self, "hog_channels", chans)
        if self.orientations < 1:
            raise ValueError("orientations must be >= 1")
        if self.pixels_per_cell < 1 or self.cells_per_block < 1:
            raise ValueError("pixels_per_cell and cells_per_block must be >= 1")
        if self.window_height is not None and self.window_height == self.window:
            object.__setattr__(self, "window_height", None)
        if self.win_w % self.pixels_per_cell or self.win_h % self.pixels_per_cell:
            raise ValueError("window and window_height must be multiples of pixels_per_cell")
        if min(self.cells_x, self.cells_y) < self.cells_per_block:
            raise ValueError("a window must hold at least one block")
        if self.spatial_size < 0 or self.hist_bins < 0:
            raise ValueError("spatial_size and hist_bins must be >= 0")
        if self.spatial_size and (self.window % self.spatial_size
                                  or self.win_h % (self.window // self.spatial_size)):
            raise ValueError("window (and window_height) must be multiples of window // spatial_size")
        if self.hist_bins and 256 % self.hist_bins:
            raise ValueError("hist_bins must divide 256")

    @property
    def win_w(self) -> int:
        """Window width in pixels."""
        return self.window

    @property
    def win_h(self) -> int:
        """Window height in pixels."""
        return self.window if self.window_height is None else self.window_height

    @property
    def cells_x(self) -> int:
        return self.win_w // self.pixels_per_cell

    @property
    def cells_y(self) -> int:
        return self.win_h // self.pixels_per_cell

    @property
    def blocks_x(self) -> int:
        """HOG block positions across a window."""
        return self.cells_x - self.cells_per_block + 1

    @property
    def blocks_y(self) -> int:
        """HOG block positions down a window."""
        return self.cells_y - self.cells_per_block + 1

    @property
    def spatial_shape(self) -> tuple[int, int]:
        """``(rows, cols)`` of the spatial-bin image (0, 0 when unused)."""
        if not self.spatial_size:
            return (0, 0)
        f = self.window // self.spatial_size
        return (self.win_h // f, self.win_w // f)

    @property
    def block_len(self) -> int:
        """Values in one block of one channel: ``cells_per_block**2 * orientations``."""
        return self.cells_per_block ** 2 * self.orientations

    @property
    def n_hog(self) -> int:
        return len(self.hog_channels) * self.blocks_x * self.blocks_y * self.block_len

    @property
    def n_spatial(self) -> int:
        h, w = self.spatial_shape
        return 3 * h * w

    @property
    def n_hist(self) -> int:
        return 3 * self.hist_bins

    @property
    def n_features(self) -> int:
        return self.n_hog + self.n_spatial + self.n_hist

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["hog_channels"] = list(self.hog_channels)
        if d["window_height"] is None:
            del d["window_height"]  # square windows: same dict as before the field existed
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "FeatureConfig":
        return _from_dict(cls, d)


@dataclass(frozen=True)
class SearchBand:
    """One search band: windows of ``scale * 64`` px in frame rows [y_start, y_stop)
    and columns [x_start, x_stop) (``None`` = frame edge)."""

    scale: float
    y_start: int
    y_stop: int
    x_start: int | None = None
    x_stop: int | None = None

    def __post_init__(self) -> None:
        if not self.scale > 0:
            raise ValueError(f"scale must be > 0, got {self.scale}")
        if self.y_stop <= self.y_start:
            raise ValueError(f"y_stop must exceed y_start, got {self.y_start}..{self.y_stop}")
        if self.x_start is not None and self.x_stop is not None and self.x_stop <= self.x_start:
            raise ValueError(f"x_stop must exceed x_start, got {self.x_start}..{self.x_stop}")


def _default_bands() -> tuple[SearchBand, ...]:
    # Each window size where cars of that size stand: all bands start 21 px above the horizon
    # (421 px, SearchConfig.reference_horizon) and reach 1.3-1.5 windows below it; 48-px
    # windows (scale 0.75, the band upsampled before HOG) for the 45-70 px cars of a wider
    # lens or a far lane, near the horizon only.
    return (
        SearchBand(0.75, 400, 460, 128, 1152),
        SearchBand(1.0, 400, 496),
        SearchBand(1.25, 400, 528),
        SearchBand(1.5, 400, 560),
        SearchBand(2.0, 400, 592),
        SearchBand(2.5, 400, 656),
        SearchBand(3.0, 400, 656),
    )


#: size ``(H, W)`` of the frames the default bands are written for (the Udacity clips)
REFERENCE_SHAPE = (720, 1280)

#: horizon row of the frames the default bands are written for (the Udacity clips, 1280x720),
#: a fraction of the frame height: 421 px, the median focus of expansion of their optical flow
#: (:mod:`fastdet.video.horizon`; their lane lines meet at about 419 px)
REFERENCE_HORIZON = 0.585


@dataclass(frozen=True)
class SearchConfig:
    """Where and how densely to search.

    bands: the search bands.
    cells_per_step: window stride in HOG cells (of the scaled band).
    threshold: a window is positive when its decision value exceeds this.
    reference_shape: ``(H, W)`` of the frames the bands are written for. A frame of another
        size gets the bands rescaled so they cover the same part of the picture: rows and
        window scales by ``H / reference H``, columns by ``W / reference W``
        (:meth:`for_frame`). ``None``: the bands are used as given, in pixels.
    reference_horizon: the horizon row of those frames, a fraction of their height.
    horizon: the horizon row of the frames searched, a fraction of their height (0 = top),
        or ``None`` for "where the reference frames have it". :meth:`for_frame` moves every
        band by ``(horizon - reference_horizon) x H`` rows after rescaling, so each window
        size is searched at the same distance from the horizon, where cars of that size are
        (a car's size and how far below the horizon it stands both scale with 1 / its
        distance, whatever the lens). Each band moves by a whole number of its window steps
        (``cells_per_step x 8 x scale`` rows; the nearest to that shift), so its windows sit
        on the grid they have at the reference horizon: a shift of a few rows would put every
        window somewhere else (F1 on ``test_small1`` 0.91 -> 0.86 for 8 rows). Bands are clipped to the frame; a band the clip leaves
        lower than its 64-px window (``64 x scale`` rows) is dropped.
    border: windows may hang this fraction of their width over the left / right frame edge
        (bands whose ``x_start`` / ``x_stop`` is ``None``), so a car cut by the border can fill
        one; the columns past the edge are filled as ``border_mode`` says (``'reflect'``:
        the frame mirrored at its edge, ``'replicate'``: its edge column repeated) and the
        boxes clipped to the frame (:mod:`fastdet.detect.bands`). ``0``: windows stay inside.
    """

    bands: tuple[SearchBand, ...] = field(default_factory=_default_bands)
    cells_per_step: int = 2
    threshold: float = 0.0
    reference_shape: tuple[int, int] | None = (720, 1280)
    reference_horizon: float = REFERENCE_HORIZON
    horizon: float | None = None
    border: float = 0.5
    border_mode: Literal["reflect", "replicate"] = "replicate"

    def for_frame(self, frame_shape: tuple[int, int]) -> "SearchConfig":
        """This config with its bands rescaled (and moved to ``horizon``) for frames of
        ``frame_shape = (H, W)``: bands in that frame's pixels (``reference_shape`` and
        ``horizon`` ``None``)."""
        h, w = (int(v) for v in frame_shape[:2])
        moved = self.horizon is not None and self.horizon != self.reference_horizon
        if not moved and (self.reference_shape is None or (h, w) == tuple(self.reference_shape)):
            return self
        rh, rw = self.reference_shape if self.reference_shape is not None else (h, w)
        fy, fx = h / rh, w / rw
        dy = (self.horizon - self.reference_horizon) * h if moved else 0.0

        def col(v: int | None) -> int | None:
            return None if v is None else min(int(round(v * fx)), w)

        bands = []
        for b in self.bands:
            step = self.cells_per_step * 8 * b.scale * fy  # rows between window positions
            d = round(dy / step) * step  # whole steps: the windows stay on the reference's grid
            a, z = int(round(b.y_start * fy + d)), int(round(b.y_stop * fy + d))
            y0, y1 = max(a, 0), min(z, h)
            if y1 > y0 and ((y0, y1) == (a, z) or y1 - y0 >= 64 * b.scale * fy):
                bands.append(SearchBand(b.scale * fy, y0, y1, col(b.x_start), col(b.x_stop)))
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
        for name in ("reference_horizon", "horizon"):
            v = getattr(self, name)
            if v is not None and not 0 <= v <= 1:
                raise ValueError(f"{name} must be a fraction of the frame height in [0, 1], got {v!r}")


def _wide_bands(traffic: str = "right") -> tuple[SearchBand, ...]:
    # 64x24 windows at 40..80 px wide: the 40-80 px wide cars seen just above the median.
    # Columns 0..~704 of 1280 where traffic drives on the right (oncoming traffic is on the
    # left of the view), 576..1280 where it drives on the left, or all. Each band is a whole
    # number of its 8 * scale px cells wide, so that the narrowed bands of
    # fastdet.video.motion resample exactly as the full band does.
    def cols(s: float) -> tuple[int, int]:
        cell = 8 * s
        if traffic == "both":
            return 0, int(1280 // cell * cell)
        n = int(704 // cell * cell)
        return (0, n) if traffic == "right" else (1280 - n, 1280)

    return tuple(SearchBand(s, 400, 400 + int(64 * s) + 24, *cols(s)) for s in (0.625, 0.75, 0.875, 1.0, 1.25))


def wide_search(traffic: Literal["right", "left", "both"] = "right") -> SearchConfig:
    """The default search of the wide-window (oncoming-traffic) model for roads where traffic
    drives on the ``'right'`` (oncoming cars on the left of the view: the default,
    :data:`WIDE_SEARCH`), on the ``'left'`` (the UK, Japan, India, Australia ...: the columns
    mirrored) or ``'both'`` (the whole width; on the camera-shift suite as good as the right
    side on each, but about 15% more CPU per frame on footage whose roadside moves fast).
    Give it as ``Detector(wide_search=...)``."""
    if traffic not in ("right", "left", "both"):
        raise ValueError(f"traffic must be 'right', 'left' or 'both', got {traffic!r}")
    return SearchConfig(bands=_wide_bands(traffic), cells_per_step=1, threshold=1.0)


#: default search of the wide-window (oncoming-traffic) model: small scales near the horizon
#: on the left of the view, where oncoming cars half hidden behind the median barrier are
#: seen where traffic drives on the right (:func:`wide_search` for the other side).
#: :class:`~fastdet.VideoDetector` narrows it each frame to where the picture moves
#: (:class:`MotionGate`).
WIDE_SEARCH = wide_search("right")


#: the side-view component's windows: 64 x 32 px (:data:`fastdet.train.components.SIDE_RECIPE`)
SIDE_WINDOW = (64, 32)
#: window widths of the side-view component's bands, in 64-px units at the reference frame
#: (80 .. 448 px of 1280: parked cars seen from the side, close cars at an angle)
SIDE_SCALES = (1.25, 1.75, 2.5, 3.5, 5.0, 7.0)


def _side_bands(scales: tuple[float, ...] = SIDE_SCALES, slack: float = 0.05) -> tuple[SearchBand, ...]:
    # A vehicle seen from the side with its top near the horizon (the camera about as high as
    # the vehicle) and its bottom about its height below: each window size is searched from
    # 0.45 to 1.15 window heights around the reference horizon, plus ``slack`` x H above and
    # below for cameras whose horizon or height differs.
    rows, hz = REFERENCE_SHAPE[0], REFERENCE_HORIZON * REFERENCE_SHAPE[0]
    out = []
    for s in scales:
        h = SIDE_WINDOW[1] * s
        y1 = min(rows, int(hz + 1.15 * h + slack * rows))
        y0 = max(0, min(int(hz - 0.45 * h - slack * rows), y1 - int(-(-h // 1))))
        out.append(SearchBand(s, y0, y1))
    return tuple(out)


def side_search() -> SearchConfig:
    """The default search of the side-view component (:class:`fastdet.Detector`
    ``components=``): :data:`SIDE_SCALES` over the whole width, a window two HOG cells from
    the next, positive above decision value 0 (probability 0.5)."""
    return SearchConfig(bands=_side_bands(), cells_per_step=2, threshold=0.0)


@dataclass(frozen=True)
class MotionGate:
    """What counts as moving for the wide-window (oncoming-traffic) model in video.

    Oncoming cars cross the view several times faster than the scenery beside them, so a
    wide window only counts when the picture inside it changed since the frame
    ``1 / reference_fps`` seconds earlier: the mean absolute difference of the grey levels
    (0..255, ``cv2.COLOR_BGR2GRAY``) of the two frames over the window's pixels must reach
    the gate, ``max(min_motion, noise_factor x noise)`` where ``noise`` is the median
    absolute difference over the whole region the wide search covers (what the picture
    moves, or its noise, everywhere). Measured at 25 fps on 1280x720 footage: the oncoming
    cars of ``test_small1`` give 28..83 (10th..90th percentile of the wide model's windows
    on them), the scenery that the wide model mistakes for cars 5..28, the region's median
    5.5 -- in the original and in its x264 (CRF 18), mp4v and MJPG copies alike: re-encoding
    does not move these figures, so an absolute ``min_motion`` is not what makes the copies
    score lower. A gate relative to the noise only lowers the original's F1 (0.911 with
    ``noise_factor`` 0 or 4, 0.904 / 0.907 / 0.903 / 0.874 with 6 / 7 / 8 / 10) and leaves
    the copies within 0.01 of where they were: it is off by default. The wide search
    itself only runs over the columns of each band that hold such a window.

    Frame rate (:meth:`lag`): at ``fps`` frames per second the frame compared with is
    ``round(fps / reference_fps)`` frames back (at least 1), so a 50 fps video (or one
    whose frames are doubled) is judged on the same 40 ms of motion as the 25 fps footage
    the thresholds were measured on. Below ``reference_fps`` the previous frame is used:
    the motion of a car grows less than in proportion to the time between frames (every
    second frame of ``test_small1``, 12.5 fps: F1 0.915 with the same gate, 0.87 with the
    gate scaled by sqrt(2), 0.83 by 2). Measured on ``test_small1`` with every frame doubled
    (50 fps): F1 0.897 comparing frames 2 apart, 0.859 comparing neighbours.

    min_motion: grey levels; ``0`` turns the gate (and the narrowing) off.
    noise_factor: the gate is at least this many times the region's median motion (``0``:
        an absolute gate, the default, see above).
    reference_fps: the frame rate the thresholds are for.
    """

    min_motion: float = 45.0
    noise_factor: float = 0.0
    reference_fps: float = 25.0

    def __post_init__(self) -> None:
        if not 0 <= self.min_motion < 256:
            raise ValueError(f"min_motion must be in [0, 256), got {self.min_motion!r}")
        if not 0 <= self.noise_factor < 256:
            raise ValueError(f"noise_factor must be in [0, 256), got {self.noise_factor!r}")
        if not 0 < self.reference_fps < 1000:
            raise ValueError(f"reference_fps must be in (0, 1000), got {self.reference_fps!r}")

    def lag(self, fps: float | None) -> int:
        """Frames between the two frames compared at ``fps`` (``None``: the reference rate)."""
        if fps is None or not fps > 0:
            return 1
        return max(1, round(fps / self.reference_fps))

    def threshold(self, noise: float) -> float:
        """The gate for a region whose median motion is ``noise`` grey levels."""
        return max(self.min_motion, self.noise_factor * noise) if self.min_motion > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "MotionGate":
        return _from_dict(cls, d)


@dataclass(frozen=True)
class HeatConfig:
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
        frame after frame. With the bundled model, 4 is the middle of the plateau on the
        two annotated clips: it gives the same boxes for every memory (4, 8, 16 frames)
        and decay (0.8, 1) tried, while 2 lets false alarms through and 6 starts to lose
        targets with a short memory, 8 loses many (README, "Accuracy").
    single_frame_threshold: ``threshold`` used by :meth:`single_frame` (one image, no
        temporal averaging to suppress false alarms, hence a stricter default: 8, the
        best single-frame value on the annotated clips for both kinds of model).
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
        "width at 40% of the peak" fits the car far better (on the two annotated clips,
        IoU-0.5 precision went from 0.72 to 1.0 at the same recall).
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
        1920x1080). A :class:`~fastdet.video.heatmap.HeatMap` for frames of ``H`` rows uses
        :meth:`for_frame`, which scales them by ``H / reference_rows``; ``None``: pixels
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
    SCORE_RANGES = {"decision": (0.0, 2.0), "probability": (0.5, 1.0)}

    def __post_init__(self) -> None:
        if int(self.n_frames) != self.n_frames or self.n_frames < 1:
            raise ValueError("n_frames must be an integer >= 1")
        if not 0 < self.decay <= 1:
            raise ValueError("decay must be in (0, 1]")
        for name in ("threshold", "single_frame_threshold"):
            v = getattr(self, name)
            if not v >= 0 or v == float("inf"):
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if (self.score_lo is None) != (self.score_hi is None):
            raise ValueError("give both score_lo and score_hi, or neither")
        if self.score_lo is not None and not self.score_hi > self.score_lo:
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
        if int(self.cell) != self.cell or self.cell < 1:
            raise ValueError("cell must be an integer >= 1")
        if self.min_width < 0 or self.min_height < 0:
            raise ValueError("min_width and min_height must be >= 0")
        if not self.max_aspect > 0:
            raise ValueError("max_aspect must be > 0")
        if self.reference_rows is not None and (int(self.reference_rows) != self.reference_rows
                                                or self.reference_rows < 1):
            raise ValueError(f"reference_rows must be an integer >= 1 or None, got {self.reference_rows!r}")

    def for_frame(self, frame_rows: int) -> "HeatConfig":
        """This config for frames of ``frame_rows`` rows: ``min_width`` / ``min_height``
        scaled by ``frame_rows / reference_rows`` (rounded), ``reference_rows`` = ``None``."""
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

    def single_frame(self, threshold: float | None = None) -> "HeatConfig":
        """This config for one image: ``n_frames=1`` and ``single_frame_threshold`` (or ``threshold``)."""
        t = self.single_frame_threshold if threshold is None else threshold
        return replace(self, n_frames=1, threshold=t)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "HeatConfig":
        return _from_dict(cls, d)


#: heat map of a wide-window model's windows (VideoDetector): no memory (the cars it is for
#: cross the view in half a second), blobs split between groups of windows half a window
#: apart (two oncoming cars side by side), a box around the cells with at least 0.3 x the
#: peak heat, wider than tall
WIDE_HEAT = HeatConfig(n_frames=1, threshold=8.0, extent=0.3, box_mode="extent", split_gap=0.5, min_height=10,
                       max_aspect=0.8)


#: heat map of the side-view component's windows (VideoDetector): the main heat map's memory
#: and threshold, boxes wider than tall; its boxes join the main ones where those found nothing
SIDE_HEAT = HeatConfig(max_aspect=1.0, min_height=10)


@dataclass(frozen=True)
class TrackerConfig:
    """The tracker that gives every vehicle box an id (:mod:`fastdet.video.track`): ByteTrack
    (Zhang et al., ECCV 2022) on the heat map's boxes.

    High-confidence boxes are the heat map's boxes (blob peak above the heat threshold);
    low-confidence boxes are the weak blobs whose peak heat is above ``low_heat`` x the
    threshold but not above it (:meth:`fastdet.video.heatmap.HeatMap.weak_boxes`).

    low_heat: fraction of each heat map's threshold a weak blob's peak must exceed to be a
        low-confidence box; ``0`` = no low-confidence boxes.
    match_iou: IoU a high-confidence box needs with a track's predicted box to continue it
        (first association; ByteTrack's ``match_thresh`` 0.8 is a cost ``1 - IoU``, i.e. 0.2).
    low_match_iou: IoU a low-confidence box needs with a track that the first association
        left unmatched (second association; ByteTrack: 0.5).
    tentative_match_iou: IoU a high-confidence box needs to continue a tentative track
        (ByteTrack: 0.3).
    min_hits: frames a track must be matched in a row before it is confirmed and gets its
        id; a tentative track that misses a frame is dropped. 1 = confirmed at once (the
        heat map already asks a vehicle for several frames of evidence).
    max_lost: frames a confirmed track that found no box is kept (predicted) before it is
        dropped; ByteTrack's ``track_buffer``.
    split_overlap: a high-confidence box that holds at least this fraction of the predicted
        boxes of two or more tracks (merged blobs of vehicles side by side) is split between
        them (:func:`fastdet.video.track.split_merged`); ``0`` = never split.
    output: which box a tracked vehicle is reported with: ``'detection'`` (the heat map's box
        of this frame) or ``'filtered'`` (the Kalman filter's estimate).
    buffer: boxes are grown by this fraction of their width / height on every side before
        the IoU of an association (the buffered IoU of C-BIoU, Yang et al., WACV 2023, whose
        first stage uses 0.3): an oncoming car 45 px wide moves 15-20 px a frame at 25 fps,
        so its new box barely overlaps its predicted one until the filter has learnt its
        velocity. 0 = plain IoU.
    std_position, std_velocity, init_velocity: Kalman noise, fractions of the box's width /
        height per frame (:class:`fastdet.video.kalman.BoxKalman`). ``std_position`` and
        ``std_velocity`` are ByteTrack's; ``init_velocity``, the uncertainty of a new track's
        velocity, is 4x ByteTrack's 10/160 (made for pedestrians at 30 fps): vehicles cross the
        view at up to half their width per frame, and with 0.25 a track knows its velocity from
        its second box.
    max_gap: ``--offline`` only: a track's gaps of at most this many frames are filled by
        linear interpolation (StrongSORT's gap interpolation, Du et al., 2023).
    extend_back: ``--offline`` only: each track is extended this many frames back from its
        first box with its starting velocity, while the box stays in the picture. Default 0:
        on the annotated clips every frame back cost precision (the first frames of an
        oncoming car are where it is still too small to be a target) and gained at most one
        true positive (README, "Tracking").
    """

    low_heat: float = 0.5
    match_iou: float = 0.2
    low_match_iou: float = 0.5
    tentative_match_iou: float = 0.3
    min_hits: int = 1
    max_lost: int = 30
    split_overlap: float = 0.5
    output: Literal["detection", "filtered"] = "detection"
    buffer: float = 0.3
    std_position: float = 1 / 20
    std_velocity: float = 1 / 160
    init_velocity: float = 0.25
    max_gap: int = 10
    extend_back: int = 0

    def __post_init__(self) -> None:
        if not 0 <= self.low_heat < 1:
            raise ValueError(f"low_heat must be in [0, 1), got {self.low_heat!r}")
        for name in ("match_iou", "low_match_iou", "tentative_match_iou"):
            v = getattr(self, name)
            if not 0 < v <= 1:
                raise ValueError(f"{name} must be in (0, 1], got {v!r}")
        for name, lo in (("min_hits", 1), ("max_lost", 0), ("max_gap", 0), ("extend_back", 0)):
            v = getattr(self, name)
            if int(v) != v or v < lo:
                raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
        if not 0 <= self.split_overlap <= 1:
            raise ValueError(f"split_overlap must be in [0, 1], got {self.split_overlap!r}")
        if not 0 <= self.buffer <= 2:
            raise ValueError(f"buffer must be in [0, 2], got {self.buffer!r}")
        if self.output not in ("detection", "filtered"):
            raise ValueError(f"output must be 'detection' or 'filtered', got {self.output!r}")
        for name in ("std_position", "std_velocity", "init_velocity"):
            v = getattr(self, name)
            if not 0 < v < float("inf"):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "TrackerConfig":
        return _from_dict(cls, d)


@dataclass(frozen=True)
class GuidedSearch:
    """How :class:`~fastdet.VideoDetector` searches the main model's bands between full scans
    (:mod:`fastdet.video.guided`): every window every ``every`` frames, near the tracked
    vehicles and recent positive windows plus a rotating strip in between.

    every: a full scan every this many frames; 1 = every frame (the exact full search).
    margin: around a track's box, this fraction of its width on each side; around a
        positive window, this fraction of the window width.
    memory: positive windows of this many recent frames guide the search.
    scales: a band searches near a track when its window side is within
        ``[scales[0], scales[1]] x`` the track's box height.
    lost_growth: a track lost for ``n`` frames gets ``n x lost_growth x`` its width more margin
        (at most one width more).
    """

    every: int = 5
    margin: float = 0.5
    memory: int = 2
    scales: tuple[float, float] = (0.4, 2.0)
    lost_growth: float = 0.25

    def __post_init__(self) -> None:
        if int(self.every) != self.every or self.every < 1:
            raise ValueError(f"every must be an integer >= 1, got {self.every!r}")
        if self.margin < 0 or self.lost_growth < 0:
            raise ValueError("margin and lost_growth must be >= 0")
        if int(self.memory) != self.memory or self.memory < 1:
            raise ValueError(f"memory must be an integer >= 1, got {self.memory!r}")
        lo, hi = self.scales
        if not 0 < lo <= hi:
            raise ValueError(f"scales must be (low, high) with 0 < low <= high, got {self.scales!r}")
        object.__setattr__(self, "scales", (float(lo), float(hi)))

    @property
    def full(self) -> bool:
        """Every frame is a full scan."""
        return self.every == 1

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "GuidedSearch":
        return _from_dict(cls, d)

"""Features of one detection window (:class:`FeatureConfig`): colour space, HOG, spatial
bins and colour histogram, and the window's size."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ._base import Config

ColorSpace = Literal["RGB", "HSV", "HLS", "LUV", "YCrCb", "YUV"]
COLOR_SPACES: tuple[str, ...] = ("RGB", "HSV", "HLS", "LUV", "YCrCb", "YUV")
#: the most features one window may have (the default has 12,576; ``train``'s largest options
#: about 51,000): the weights, every training row and the search's correlation blocks grow with it
MAX_FEATURES = 65_536
#: the most HOG values a search band's block map holds per pixel and channel
#: (``cells_per_block**2 * orientations / pixels_per_cell**2``; the default 1, ``train``'s
#: largest options 4): the block map of a 1280x256 band is that many times its pixels
MAX_BLOCK_VALUES_PER_PIXEL = 16
#: the widest (and tallest) window in pixels
MAX_WINDOW = 1024


@dataclass(frozen=True)
class FeatureConfig(Config):
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
        if not 1 <= self.window <= MAX_WINDOW or (self.window_height is not None
                                                   and not 1 <= self.window_height <= MAX_WINDOW):
            raise ValueError(f"window and window_height must be in 1..{MAX_WINDOW}")
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
        per_pixel = self.block_len / self.pixels_per_cell ** 2
        if per_pixel > MAX_BLOCK_VALUES_PER_PIXEL:
            raise ValueError(f"cells_per_block**2 * orientations / pixels_per_cell**2 is {per_pixel:g}: a search "
                             f"band's HOG block map would hold that many values per pixel and channel "
                             f"(at most {MAX_BLOCK_VALUES_PER_PIXEL})")
        if self.n_features > MAX_FEATURES:
            raise ValueError(f"{self.n_features} features per window (at most {MAX_FEATURES})")

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

    _OMIT_NONE = ("window_height",)  # square windows: the same dict as before the field existed


#: side of the default (square) window in pixels, and of its HOG cells: the units the
#: default search bands are written in (a band of scale ``s`` holds windows of ``s x WINDOW`` px)
WINDOW = FeatureConfig.window
CELL = FeatureConfig.pixels_per_cell

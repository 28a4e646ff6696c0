"""Search bands: cropping and scaling a band, window positions, windows → frame boxes.

A band (:class:`~fastdet.config.SearchBand`) is the frame region ``[y_start, y_stop) x
[x_start, x_stop)``, resized by ``1/scale`` with ``cv2.resize(.., INTER_LINEAR)`` to
``(int(w / scale), int(h / scale))`` (``INTER_AREA`` instead for a shrunk band of a search
with ``shrink='area'``); a 64-px window in the scaled band is a
``64 * scale``-px box in the frame (``win_w * scale`` by ``win_h * scale`` in general).
Windows sit on the HOG cell grid of the scaled band, ``cells_per_step`` cells apart.

Windows over the border: a band that reaches the left (right) edge of the frame
(``x_start`` (``x_stop``) ``None``) may start (end) ``border x window width`` frame pixels
beyond it (``band_geometry(..., border=)``), so a car cut by the image border can sit inside
a window. The missing columns are the frame's own, mirrored at its edge
(``cv2.BORDER_REFLECT_101``) or its edge column repeated (``BORDER_REPLICATE``):
exactly the band of the frame padded that way (:func:`scaled_band`), and the window boxes
are clipped to the frame (:func:`window_boxes`).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..boxes import window_grid_boxes
from ..config import FeatureConfig, SearchBand


@dataclass(frozen=True)
class BandGeometry:
    """Where a band is and how many windows it holds (all in pixels / windows)."""

    band: SearchBand
    x0: int
    y0: int
    x1: int
    y1: int
    scaled_w: int
    scaled_h: int
    nx: int  # window positions across
    ny: int  # window positions down
    step: int  # cells between positions
    pad_left: int = 0  # columns of the band left of the frame (x0 = -pad_left)
    pad_right: int = 0  # columns of the band right of the frame (x1 = frame width + pad_right)
    border_mode: str = "reflect"  # how those columns are filled: "reflect" or "replicate"
    shrink: str = "linear"  # how the band is shrunk (scale > 1): "linear" (INTER_LINEAR) or "area" (INTER_AREA)

    @property
    def n_windows(self) -> int:
        return self.nx * self.ny


BORDER_MODES = {"reflect": cv2.BORDER_REFLECT_101, "replicate": cv2.BORDER_REPLICATE}


def band_geometry(band: SearchBand, frame_shape: tuple[int, int], config: FeatureConfig,
                  cells_per_step: int, border: float = 0.0, border_mode: str = "reflect",
                  shrink: str = "linear") -> BandGeometry:
    """Geometry of ``band`` on a frame of ``frame_shape = (H, W)``; ``ValueError`` if the band
    does not fit the frame. ``border``: at a frame edge the band reaches (``x_start`` /
    ``x_stop`` ``None``), let it run ``round(border x win_w x scale)`` px past the edge,
    filled as ``border_mode`` says (module docstring). ``shrink``: the resize of a band shrunk
    to its scale, ``'linear'`` or ``'area'`` (:attr:`SearchConfig.shrink
    <fastdet.config.SearchConfig>`)."""
    h, w = frame_shape
    if border_mode not in BORDER_MODES:
        raise ValueError(f"border_mode must be one of {sorted(BORDER_MODES)}, got {border_mode!r}")
    if shrink not in ("linear", "area"):
        raise ValueError(f"shrink must be 'linear' or 'area', got {shrink!r}")
    pad = round(border * config.win_w * band.scale) if border > 0 else 0
    pl = pad if band.x_start is None else 0
    pr = pad if band.x_stop is None else 0
    x0 = -pl if band.x_start is None else band.x_start
    x1 = w + pr if band.x_stop is None else band.x_stop
    y0, y1 = band.y_start, band.y_stop
    if y0 < 0 or x0 + pl < 0 or y1 > h or x1 - pr > w:
        raise ValueError(f"search band {band} does not fit a {w}x{h} frame "
                         f"(needs at least {x1 - pr}x{y1}); pass a larger frame or another SearchConfig")
    sw, sh = int((x1 - x0) / band.scale), int((y1 - y0) / band.scale)
    ppc, cpb = config.pixels_per_cell, config.cells_per_block
    nbx, nby = sw // ppc - cpb + 1, sh // ppc - cpb + 1
    nx = (nbx - config.blocks_x) // cells_per_step + 1 if nbx >= config.blocks_x else 0
    ny = (nby - config.blocks_y) // cells_per_step + 1 if nby >= config.blocks_y else 0
    return BandGeometry(band, x0, y0, x1, y1, sw, sh, nx, ny, cells_per_step, pl, pr, border_mode, shrink)


@dataclass(frozen=True)
class PaddedFrame:
    """Frame rows ``[y0, y0 + len(pixels))`` with ``pad`` columns added on each side as
    ``border_mode`` says: ``pixels (rows, W + 2*pad, 3) uint8``. Made once per frame
    (:func:`pad_frame`) for all the bands that run past the frame edge: a band's padded crop
    is a view of it, as the padding of column ``-k`` (``W - 1 + k``) does not depend on how
    wide the padding is."""

    pixels: np.ndarray
    y0: int
    pad: int
    border_mode: str

    def covers(self, geo: BandGeometry) -> bool:
        """Whether ``geo``'s padded crop is a view of this."""
        return (geo.border_mode == self.border_mode and geo.y0 >= self.y0
                and geo.y1 <= self.y0 + self.pixels.shape[0]
                and max(geo.pad_left, geo.pad_right) <= self.pad)


def pad_frame(frame: np.ndarray, geos: list[BandGeometry]) -> PaddedFrame | None:
    """One :class:`PaddedFrame` for the bands of ``geos`` that run past the frame edge (those
    of the first such band's border mode): their rows, their widest padding. ``None`` when
    fewer than two bands would share it (then :func:`scaled_band` pads each band itself)."""
    padded = [g for g in geos if g.pad_left or g.pad_right]
    if len(padded) < 2:
        return None
    mode = padded[0].border_mode
    padded = [g for g in padded if g.border_mode == mode]
    if len(padded) < 2:
        return None
    y0, y1 = min(g.y0 for g in padded), max(g.y1 for g in padded)
    pad = max(max(g.pad_left, g.pad_right) for g in padded)
    pixels = cv2.copyMakeBorder(frame[y0:y1], 0, 0, pad, pad, BORDER_MODES[mode])
    return PaddedFrame(pixels, y0, pad, mode)


def scaled_band(frame: np.ndarray, geo: BandGeometry, padded: PaddedFrame | None = None) -> np.ndarray:
    """The band's pixels resized by ``1/scale``: ``(scaled_h, scaled_w, 3) uint8`` (with the
    columns past the frame edge filled as ``geo.border_mode`` says: cut from ``padded`` (a
    :func:`pad_frame` of this frame) when it covers the band, else padded here)."""
    if (geo.pad_left or geo.pad_right) and padded is not None and padded.covers(geo):
        roi = padded.pixels[geo.y0 - padded.y0: geo.y1 - padded.y0, padded.pad + geo.x0: padded.pad + geo.x1]
    else:
        roi = frame[geo.y0: geo.y1, geo.x0 + geo.pad_left: geo.x1 - geo.pad_right]
        if geo.pad_left or geo.pad_right:
            roi = cv2.copyMakeBorder(roi, 0, 0, geo.pad_left, geo.pad_right, BORDER_MODES[geo.border_mode])
    if geo.scaled_w == roi.shape[1] and geo.scaled_h == roi.shape[0]:
        return np.ascontiguousarray(roi)
    area = geo.shrink == "area" and geo.scaled_w < roi.shape[1] and geo.scaled_h < roi.shape[0]
    return cv2.resize(roi, (geo.scaled_w, geo.scaled_h), interpolation=cv2.INTER_AREA if area else cv2.INTER_LINEAR)


def window_boxes(geo: BandGeometry, rows: np.ndarray, cols: np.ndarray, config: FeatureConfig) -> np.ndarray:
    """Frame boxes ``(N, 4) int32 x1, y1, x2, y2`` of the windows at positions (rows, cols),
    clipped to the frame where the band runs past its edge."""
    boxes = window_grid_boxes(geo.x0, geo.y0, rows, cols, geo.step, config.pixels_per_cell,
                              geo.band.scale, config.win_w, config.win_h)
    if geo.pad_left or geo.pad_right:
        np.clip(boxes[:, 0::2], geo.x0 + geo.pad_left, geo.x1 - geo.pad_right, out=boxes[:, 0::2])
    return boxes

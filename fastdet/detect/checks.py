"""Is a picture usable by a detector? Checked on the first frame, before any output exists.

- Size (:func:`check_frame_size`): the default search is written for 1280x720 and scaled
  to other sizes (:meth:`~fastdet.config.SearchConfig.for_frame`); a frame is refused
  when a band of the main search does not fit it, holds no window, or its windows would
  be smaller than :data:`MIN_WINDOW_PX` pixels (the band would be blown up many times over:
  a 1280x16 frame took 850 ms and found nothing). The message gives the minimum size.
- Colour (:func:`check_colour`): the models use colour features (YCrCb histograms and
  spatial bins); on a greyscale picture -- the three channels equal, as OpenCV gives a
  grey JPEG or video -- they find nothing (0 positive windows in the grey copies of the six
  test images against 123 in the colour ones), so a grey picture is refused rather than
  giving an empty answer that looks like "no vehicles". A video is judged on more than its
  first frame when that one is grey (``more``: the next frames and a sample through the
  file, :meth:`~fastdet.io.reader.FrameReader.colour_sample`): a colour video with a grey
  or faded intro runs; only the first frame is looked at when it is colour (no cost).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import replace
from typing import Any

import numpy as np

from ..errors import DataError
from .bands import band_geometry

#: smallest window, in frame pixels, the main search may use
MIN_WINDOW_PX = 16
#: channels within this many grey levels count as equal (a grey picture through a lossy codec:
#: up to 3; real colour footage has 10% of its pixels within 6, test_small1.mp4)
GREY_TOLERANCE = 6
#: a picture whose grey levels vary less than this (standard deviation) is not judged: a
#: black or flat frame (a fade-in) says nothing about colour
MIN_CONTRAST = 8.0


def _problem(detector: Any, shape: tuple[int, int]) -> str | None:
    """Why the main search cannot run on frames of ``shape = (H, W)`` (``None``: it can)."""
    sc = detector.scorers[0]
    try:
        search = sc.search.for_frame(shape, sc.config.win_w, sc.config.pixels_per_cell)
    except ValueError as exc:
        return str(exc)
    for band in search.bands:
        if band.scale * min(sc.config.win_w, sc.config.win_h) < MIN_WINDOW_PX:
            return f"its windows would be smaller than {MIN_WINDOW_PX} px"
        try:
            geo = band_geometry(band, shape, sc.config, search.cells_per_step)
        except ValueError as exc:
            return str(exc)
        if geo.n_windows == 0:
            return "a search band holds no window"
    return None


def minimum_frame_size(detector: Any, aspect: float = 16 / 9) -> tuple[int, int]:
    """The smallest ``(W, H)`` of frames of width/height ratio ``aspect`` the detector's
    main search runs on (a search in fixed pixels: the size it needs)."""
    sc = detector.scorers[0]
    ref = sc.search.reference_shape
    if ref is None:
        h = max(b.y_stop for b in sc.search.bands)
        w = max(b.x_stop or 0 for b in sc.search.bands) or math.ceil(h * aspect)
        return max(w, math.ceil(h * aspect)), h
    lo, hi = 1, 8 * ref[0]
    while lo < hi:  # fits is monotonic in the height at a fixed aspect ratio
        mid = (lo + hi) // 2
        if _problem(detector, (mid, max(1, round(mid * aspect)))) is None:
            hi = mid
        else:
            lo = mid + 1
    return max(1, round(lo * aspect)), lo


def check_frame_size(detector: Any, shape: tuple[int, ...], source: str) -> None:
    """``DataError`` naming the minimum size when frames of ``shape`` are too small (or too
    thin) for ``detector``'s main search. Detectors without ``scorers`` are not checked."""
    if not hasattr(detector, "scorers"):
        return
    h, w = int(shape[0]), int(shape[1])
    why = _problem(detector, (h, w))
    if why is None:
        return
    aspect = w / h if h else 0.0
    mw16, mh16 = minimum_frame_size(detector)
    need = f"at least {mw16}x{mh16} (16:9)"
    if 0.2 <= aspect <= 5:
        mw, mh = minimum_frame_size(detector, aspect)
        if (mw, mh) != (mw16, mh16):
            need += f" or {mw}x{mh} at this aspect ratio"
    else:
        need += ", and no thinner than 1:5 either way"
    raise DataError(f"{source}: frames of {w}x{h} are too small for the vehicle search: it needs {need}")


def is_grey(frame: np.ndarray) -> bool:
    """``(H, W, 3) uint8`` ``frame`` is a greyscale picture: its three channels are equal
    (within :data:`GREY_TOLERANCE` on 99% of a sample of its pixels) and it has contents
    (grey levels varying by at least :data:`MIN_CONTRAST`; a flat or black frame is not
    called grey)."""
    f = np.asarray(frame)
    if f.ndim == 3 and f.shape[2] == 1:
        f = f[:, :, 0]
    step = max(1, int(math.sqrt(f.shape[0] * f.shape[1] / 40000)))
    s = f[::step, ::step].astype(np.int16)
    if s.std() < MIN_CONTRAST:
        return False
    if s.ndim == 2:
        return True
    spread = s.max(axis=2) - s.min(axis=2)
    return bool(np.mean(spread <= GREY_TOLERANCE) >= 0.99)


def check_colour(detector: Any, frame: np.ndarray, source: str,
                 more: Callable[[], Iterable[np.ndarray]] | None = None) -> None:
    """``DataError`` for a greyscale picture (see the module docstring); only for fastdet's
    own :class:`~fastdet.detect.Detector` (an injected detector may not need colour). A video:
    when ``frame`` (its first) is grey, ``more()`` gives further frames, and any one in colour
    makes it colour footage."""
    if not hasattr(detector, "scorers") or not is_grey(frame):
        return
    what = "picture is"
    for f in more() if more is not None else ():
        if not is_grey(f):
            return
        what = "video is (its first frames and a sample through it)"
    raise DataError(f"{source}: the {what} greyscale; fastdet's models use colour and find no "
                    f"vehicles in grey pictures: give it the colour original")


def _horizon_fits(detector: Any, shape: tuple[int, int], horizon: float) -> bool:
    """Every model's search keeps a band in frames of ``shape`` with the horizon there."""
    for sc in detector.scorers:
        try:
            replace(sc.search, horizon=horizon).for_frame(shape)
        except ValueError:
            return False
    return True


def check_horizon(detector: Any, shape: tuple[int, ...], horizon: Any, source: str,
                  given_as: str = "--horizon") -> None:
    """``DataError`` when a fixed ``horizon`` (a fraction of the frame height) leaves some
    model of ``detector`` no search band in frames of ``shape``; the message names the horizon
    as ``given_as`` says it came and gives the horizons that do. ``'auto'`` / ``None`` and
    detectors without ``scorers`` pass."""
    if isinstance(horizon, bool) or not isinstance(horizon, (int, float)) or not hasattr(detector, "scorers"):
        return
    h, w = int(shape[0]), int(shape[1])
    if not (math.isfinite(horizon) and 0 <= horizon < 1):
        raise DataError(f"--horizon must be a fraction of the frame height in [0, 1), got {horizon!r}")
    if _horizon_fits(detector, (h, w), float(horizon)):
        return
    ok = [k / 200 for k in range(200) if _horizon_fits(detector, (h, w), k / 200)]
    room = (f"the search bands need it between {min(ok):g} and {max(ok):g} of the height" if ok
            else "no horizon leaves room for them")
    raise DataError(f"{source}: {given_as} {horizon:g} leaves no room for a search band below it in "
                    f"{w}x{h} frames; {room}")


def check_frame(detector: Any, frame: np.ndarray, source: str, horizon: Any = None,
                more: Callable[[], Iterable[np.ndarray]] | None = None, horizon_given_as: str = "--horizon") -> None:
    """The checks on a first frame: size (:func:`check_frame_size`), colour (``more``: the
    video's further frames, :func:`check_colour`), and a fixed ``horizon`` that leaves room
    for the search bands (:func:`check_horizon`; ``horizon_given_as``: where it came from)."""
    check_frame_size(detector, frame.shape, source)
    check_colour(detector, frame, source, more)
    check_horizon(detector, frame.shape, horizon, source, horizon_given_as)

"""Tracking-guided search: which windows of the main search a video frame needs.

The classic write-ups' own speed trick, with the tracker's help: scan every window of every
band every ``every`` frames (and on the first frame, after :meth:`SearchPlanner.reset` (a
cut) and after a vehicle's track is lost); on the frames between, score only

- the windows near each live track: its latest and predicted boxes, grown by ``margin`` x
  their width (more for a track that has been lost a while), in the bands whose window size
  suits the box (``scales``: window side within that range of the box height);
- the windows near the positive windows of the last ``memory`` frames, in the band they
  fired in (what feeds the heat map: a car that is not tracked yet, or one the heat map is
  building up);
- a rotating strip ``1 / every`` of the frame wide, in every band, so a new vehicle is
  seen within ``every`` frames anywhere even between full scans.

A scored window gets exactly the decision value of the full search
(:meth:`fastdet.Detector.detect` ``columns``); what changes is only which windows are looked
at. :class:`~fastdet.config.GuidedSearch` ``(every=1)`` is the full search on every frame.
"""
from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np

from ..config import GuidedSearch
from ..detect.bands import BandGeometry
from ..detections import Detections


def merge_spans(spans: list[tuple[int, int]], gap: int = 2) -> list[tuple[int, int]]:
    """Sorted, merged ``(j0, j1)`` ranges; ranges less than ``gap`` columns apart join (a
    separate range costs a window step of margin on each side)."""
    out: list[tuple[int, int]] = []
    for j0, j1 in sorted(s for s in spans if s[1] > s[0]):
        if out and j0 <= out[-1][1] + gap:
            out[-1] = (out[-1][0], max(out[-1][1], j1))
        else:
            out.append((j0, j1))
    return out


class SearchPlanner:
    """Decides, frame after frame, which windows of the main bands to score.

    ``plan(geos, win_w, cell, shape)`` before a frame's detection: ``None`` (score
    everything) or one list of window-column ranges per band; ``observe(windows, tracks,
    lost)`` after it, with the frame's positive main-model windows and the tracker's live
    tracks; ``reset()`` at a cut. A frame of another size is scanned in full.
    """

    def __init__(self, config: GuidedSearch | None = None) -> None:
        self.config = config if config is not None else GuidedSearch()
        self.reset()

    def reset(self) -> None:
        # each recent frame's positive windows: {scale: [(x1, x2), ...]} (the order of the
        # spans does not matter: merge_spans sorts them)
        self._recent: deque[dict[float, list[tuple[float, float]]]] = deque(maxlen=self.config.memory)
        self._close_cache: dict[tuple[float, float], bool] = {}
        self._tracks: list[tuple[np.ndarray, float]] = []  # (box, extra margin in widths)
        self._since_full = 0
        self._force = True
        self._n = 0  # frames planned since the reset
        self._shape: tuple[int, int] | None = None
        self.full_scans = 0

    def plan(self, geos: Sequence[BandGeometry], win_w: int, cell: int,
             shape: tuple[int, int]) -> list[list[tuple[int, int]]] | None:
        """Window-column ranges of each band for the next frame (``None``: all); ``win_w``
        and ``cell``: the window width and cell size (scaled-band pixels); ``shape``: the
        frame's ``(H, W)``."""
        c = self.config
        n = self._n
        self._n += 1
        shape = (int(shape[0]), int(shape[1]))
        if shape != self._shape:
            self._shape, self._force = shape, True
        width = shape[1]
        if c.full or self._force or self._since_full + 1 >= c.every:
            self._force = False
            self._since_full = 0
            self.full_scans += 1
            return None
        self._since_full += 1
        strip = (n % c.every) * width / c.every, (n % c.every + 1) * width / c.every
        plan = []
        for geo in geos:
            s = geo.band.scale
            ps, ws = geo.step * cell * s, win_w * s

            def cols(x0: float, x1: float) -> tuple[int, int]:
                j0 = math.floor((x0 - ws - geo.x0) / ps) + 1
                j1 = math.ceil((x1 - geo.x0) / ps)
                return max(j0, 0), min(j1, geo.nx)

            spans = [cols(*strip)]
            pad = c.margin * ws
            for by_scale in self._recent:  # the windows of this band's scale (np.isclose)
                for u, xs in by_scale.items():
                    if self._close(u, s):
                        for x0, x1 in xs:
                            spans.append(cols(x0 - pad, x1 + pad))
            for box, extra in self._tracks:
                bw, bh = box[2] - box[0], box[3] - box[1]
                if c.scales[0] * bh <= ws <= c.scales[1] * bh:
                    pad = (c.margin + extra) * bw
                    spans.append(cols(box[0] - pad, box[2] + pad))
            # a range of its own costs HOG over a window and a step of margin on each side
            plan.append(merge_spans(spans, gap=win_w // (geo.step * cell) + 2))
        return plan

    @staticmethod
    def _group(windows: Detections) -> dict[float, list[tuple[float, float]]]:
        """``{scale: [(x1, x2) of each window of that scale]}`` (``scale`` as float32 values;
        nothing for windows without a scale)."""
        if windows.scale is None or not len(windows):
            return {}
        out: dict[float, list[tuple[float, float]]] = {}
        for u, (a, _, b, _) in zip(np.asarray(windows.scale, np.float32).tolist(), windows.boxes.tolist()):
            if u == u:  # np.isclose(NaN, s) is False: no band's
                out.setdefault(u, []).append((a, b))
        return out

    def _close(self, u: float, s: float) -> bool:
        """``np.isclose`` of a float32 window scale ``u`` and a band's scale ``s`` (cached:
        a video has a few of each)."""
        key = (u, s)
        v = self._close_cache.get(key)
        if v is None:
            v = self._close_cache[key] = bool(np.isclose(np.array([u], np.float32), s)[0])
        return v

    def observe(self, windows: Detections, tracks: Sequence[tuple[np.ndarray, np.ndarray, int]],
                lost: bool) -> None:
        """After a frame: its positive windows of the main model (``windows``, with
        ``scale``), the live tracks as ``(latest box, predicted box, frames since seen)`` and
        whether a confirmed track was lost in it (the next frame is then a full scan)."""
        self._recent.append(self._group(windows))
        g = self.config.lost_growth
        self._tracks = []
        for box, pred, missed in tracks:
            both = np.array([min(box[0], pred[0]), min(box[1], pred[1]), max(box[2], pred[2]), max(box[3], pred[3])],
                            np.float64)
            self._tracks.append((both, min(g * missed, 1.0)))
        if lost:
            self._force = True

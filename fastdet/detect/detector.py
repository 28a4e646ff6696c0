"""``Detector``: the positive windows of one frame, every window of every band scored at once.

Per band: crop, resize by ``1/scale``, colour-convert once; HOG block map, spatial-bin
map and histogram-weight integral image once; then one numba kernel gives the decision
value of every window position (``fastdet.detect.scoring.dense_scores``). The result equals
the classic per-window pipeline (skimage HOG of the scaled band, the window's blocks sliced
out, the window's own spatial and histogram features, ``scaler.transform``,
``decision_function``) to floating-point rounding; ``tests/detect/test_detector.py`` checks every
window of every default band. One model's bands are scored by
:mod:`fastdet.detect.band_scorer`.

Training crops are 64x64 images whose HOG has zeroed gradients on the crop's border; in
the band, a window's edge pixels see their real neighbours. So search features differ from
training features in the outermost pixel ring: the classic pipeline has the same mismatch,
and it is what HOG sub-sampling buys its speed with. Measured on the test images
(``tools/studies/crop_vs_band.py``): band decision values are about 1.1 higher than those of the same
windows as crops, and the sign differs on 0.6% of windows.
"""
from __future__ import annotations

import os
import threading
import time
import warnings
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numba
import numpy as np

from .._numba import ensure_compiled, serial_kernels
from ..config import ONCOMING_SEARCH, SearchBand, SearchConfig
from ..detections import FIRST_COMPONENT_PART, MAIN_PART, ONCOMING_PART, Detections
from ..errors import ModelError
from ..features import _hog_kernels
from ..model import Model, load_model
from . import _score_kernels
from .band_scorer import _Scorer, group_band_scores, image_key
from .bands import BandGeometry, band_geometry, pad_frame, window_boxes

#: the numba kernels :meth:`Detector.detect` runs (each in the signatures its module lists)
KERNELS = (_hog_kernels.cell_hists_u8, _hog_kernels.normalize_blocks_fast, _score_kernels.dense_scores,
           _score_kernels.hist_weight_integral)


@dataclass
class DetectStats:
    """What one :meth:`Detector.detect` call did, recorded into an object the caller passes
    (the Detector keeps nothing per call, so one Detector may serve several threads).

    timings: seconds per stage (``resize_colour``, ``hog``, ``score``), summed over bands
        (and over band threads: it can exceed the wall time).
    bands: one ``(part, geometry, decision values (ny, nx) float64)`` per searched band.
    """

    timings: dict[str, float] = field(default_factory=dict)
    bands: list[tuple[int, BandGeometry, np.ndarray]] = field(default_factory=list)


class Detector:
    """Finds vehicle windows in frames.

    model: a :class:`~fastdet.model.Model`, a path to a model file, or ``None`` for the
        bundled default model (64x64 windows).
    search: where and how densely to search with it (default :class:`~fastdet.config.SearchConfig`).
    oncoming: an optional second model, for oncoming traffic: wide windows
        (``FeatureConfig.window_height`` < ``window``, trained with ``fastdet train
        --window-rows``) for vehicles half hidden behind a barrier, e.g. oncoming traffic above
        the median; ``None`` (default) = off. The bundled one is
        ``fastdet.config.ONCOMING_MODEL_PATH``; :class:`fastdet.VideoDetector` runs it by
        default, searching only where the picture moves (:mod:`fastdet.video.motion`).
    oncoming_search: its search bands (default :data:`fastdet.config.ONCOMING_SEARCH`).
    horizon: the horizon row of the frames, a fraction of their height, for every search
        (:attr:`SearchConfig.horizon <fastdet.config.SearchConfig>`: the bands move with it);
        ``None`` keeps the searches' own. Change it later with :meth:`set_horizon`.
    components: more whole-vehicle models, each with its own search: ``(model, search)``
        pairs. Their windows are tagged ``FIRST_COMPONENT_PART + i``; the guided search plans
        their bands as the main model's (``columns``). A main model that carries a side-view
        component (:attr:`Model.side <fastdet.model.Model.side>`, ``fastdet adapt``) adds it as the
        first, with ``search`` (those given follow it: the first of them is part
        ``FIRST_COMPONENT_PART + 1``); ``side=False`` leaves it out (the main model's own windows
        only). :func:`fastdet.train.windows.false_window_scores` scores several
        models on the same windows with them. All models must give the same
        kind of score (:attr:`Model.score_kind <fastdet.model.Model.score_kind>`).
    wide, wide_search: the former names of ``oncoming`` and ``oncoming_search``; deprecated
        (a :class:`DeprecationWarning`), they will be removed.

    ``detect(frame)`` returns the positive windows of every model (``oncoming_bands`` narrows the
    oncoming model's search); :class:`fastdet.VideoDetector` turns them into one box per vehicle
    with a heat map over recent frames.
    """

    #: ``detect`` takes ``columns`` (:class:`fastdet.video.detector.ColumnSearch`)
    column_search = True
    #: the numba kernels :meth:`detect` runs (what a warm-up compiles / loads)
    kernels: ClassVar[tuple[Any, ...]] = KERNELS

    def __init__(self, model: Model | str | os.PathLike | None = None, search: SearchConfig | None = None,
                 oncoming: Model | str | os.PathLike | None = None, oncoming_search: SearchConfig | None = None,
                 horizon: float | None = None,
                 components: Sequence[tuple[Model | str | os.PathLike, SearchConfig]] = (), *, side: bool = True,
                 wide: Model | str | os.PathLike | None = None, wide_search: SearchConfig | None = None):
        if wide is not None or wide_search is not None:
            if oncoming is not None or oncoming_search is not None:
                raise TypeError("Detector: give oncoming= and oncoming_search= (wide= and wide_search= are "
                                "their former names), not both")
            warnings.warn("Detector(wide=, wide_search=) is deprecated; use Detector(oncoming=, oncoming_search=)",
                          DeprecationWarning, stacklevel=2)
            oncoming, oncoming_search = wide, wide_search
        self.model = model if isinstance(model, Model) else load_model(model)
        if self.model.config.window_height is not None:
            name = "the main model" if model is None or isinstance(model, Model) else os.fspath(model)
            cfg = self.model.config
            raise ModelError(f"{name}: a wide-window model ({cfg.win_w}x{cfg.win_h} windows) cannot be the "
                             f"main model, whose windows are square; give it as the oncoming model")
        self.search = search if search is not None else SearchConfig()
        self.config = self.model.config
        self.scorers = [_Scorer(self.model, self.search)]
        self.parts = [MAIN_PART]  # the Detections.part of each scorer's windows
        self.oncoming_model: Model | None = None
        if oncoming is not None:
            self.oncoming_model = oncoming if isinstance(oncoming, Model) else load_model(oncoming)
            if self.oncoming_model.config.window_height is None:
                name = "the oncoming model" if isinstance(oncoming, Model) else os.fspath(oncoming)
                raise ModelError(f"{name}: not a wide-window model (its windows are square); "
                                 f"train one with `fastdet train --window-rows A B`")
            self._check_kind(self.oncoming_model, oncoming, "the oncoming model")
            self.scorers.append(_Scorer(self.oncoming_model,
                                        oncoming_search if oncoming_search is not None else ONCOMING_SEARCH))
            self.parts.append(ONCOMING_PART)
        self.components: list[Model] = []
        if side and self.model.side is not None:  # the camera's side-view component: the main model's search
            components = [(self.model.side, self.search), *components]
        for i, (comp, comp_search) in enumerate(components):
            m = comp if isinstance(comp, Model) else load_model(comp)
            self._check_kind(m, comp, f"component {i + 1}")
            if not isinstance(comp_search, SearchConfig):
                raise TypeError(f"component {i + 1}: its search must be a SearchConfig, "
                                f"got {type(comp_search).__name__}")
            self.components.append(m)
            self.scorers.append(_Scorer(m, comp_search))
            self.parts.append(FIRST_COMPONENT_PART + i)
        self._scorer_of = dict(zip(self.parts, self.scorers))
        if horizon is not None:
            self.set_horizon(horizon)
        self.score_kind = self.model.score_kind
        self._pool: ThreadPoolExecutor | None = None  # band threads, made on the first multi-threaded detect
        self._pool_size = 0
        self._pool_lock = threading.Lock()

    def _check_kind(self, m: Model, given: object, label: str) -> None:
        """``ModelError`` unless ``m`` gives the main model's kind of score."""
        if m.score_kind != self.model.score_kind:
            name = label if isinstance(given, Model) else os.fspath(given)  # type: ignore[call-overload]
            raise ModelError(f"{name}: a {m.classifier} model gives {m.score_kind} scores, the main model "
                             f"{self.model.score_kind} scores; train both with the same --classifier")

    @property
    def main_parts(self) -> list[int]:
        """The parts whose windows are vehicles' whole boxes (the main model and every
        component; not the oncoming model's barrier-cut middle rows), in scorer order."""
        return [p for p in self.parts if p != ONCOMING_PART]

    @property
    def horizon(self) -> float | None:
        """The main search's horizon (fraction of the frame height; ``None``: the reference's)."""
        return self.scorers[0].search.horizon

    def set_horizon(self, horizon: float | None) -> None:
        """Search frames whose horizon is at row ``horizon`` x H (``None``: where the reference
        frames have it): every band of both models moves with it (:meth:`SearchConfig.for_frame
        <fastdet.config.SearchConfig.for_frame>`). Call it between frames, not during one."""
        for sc in self.scorers:
            sc.search = replace(sc.search, horizon=None if horizon is None else float(horizon))

    def warmup(self) -> None:
        """Load (or compile) the numba kernels now rather than on the first frame (a first
        run compiles them on every core, after saying so: :func:`fastdet._numba.ensure_compiled`),
        then run them once on a small image."""
        ensure_compiled(KERNELS)
        for sc in self.scorers:
            cfg = sc.config
            tiny = np.zeros((cfg.win_h * 2, cfg.win_w * 2, 3), np.uint8)
            geo = band_geometry(SearchBand(1.0, 0, tiny.shape[0]), tiny.shape[:2], cfg, sc.search.cells_per_step)
            sc.band_scores(tiny, geo, None)
            sc.band_scores(tiny, geo, None, serial=True)

    def band_scores(self, frame: np.ndarray, geo: BandGeometry, timings: dict[str, float] | None = None,
                    part: int = 0) -> np.ndarray:
        """Decision values of every window position of one band: ``(geo.ny, geo.nx) float64``
        (``part`` 0: the main model, 1: the oncoming model, ``FIRST_COMPONENT_PART + i``: component ``i``)."""
        return self._scorer_of[part].band_scores(frame, geo, timings)

    def _all_band_scores(self, frame: np.ndarray, geos: list, timings: dict[str, float],
                         spans: Sequence[Sequence[tuple[int, int]] | None] | None = None) -> list[np.ndarray]:
        """Scores of every band. With more than one Numba thread, the bands are shared
        between that many Python threads -- the calling one and ``n - 1`` pool threads --,
        each running the kernels single-threaded (all of them release the GIL) and taking the
        next band, biggest first, when it is done: a frame is a dozen small bands, and one
        band per core costs far less than waking a team of OpenMP workers for every kernel.
        (Letting the caller work instead of wait: one thread fewer to schedule, 15% less wall
        time a frame in ``video`` at 2 threads.) ``timings`` then adds up the work of all
        threads (it can exceed the wall time)."""
        n_threads = numba.get_num_threads()
        spans = list(spans) if spans is not None else []
        spans += [None] * (len(geos) - len(spans))
        # the bands past the frame edge cut their padded crops from one padded copy of the
        # frame (not every band its own): the scaled bands are the same, bit for bit
        t0 = time.perf_counter()
        padded = pad_frame(frame, [g for i, (_, g) in enumerate(geos) if self._needs_pixels(g, spans[i])])
        timings["resize_colour"] = timings.get("resize_colour", 0.0) + (time.perf_counter() - t0)
        # one job per band image: the bands of several models with the same pixels, features and
        # columns to score (a main model's and its side-view component's) share it
        groups: dict[tuple[Any, ...], list[int]] = {}
        for i, (p, g) in enumerate(geos):
            given = spans[i]
            sp = None if given is None else tuple((int(a), int(b)) for a, b in given)
            groups.setdefault((image_key(g), self._scorer_of[p].feature_key, sp), []).append(i)
        jobs = list(groups.values())
        results: list[Any] = [None] * len(geos)

        def score(job: list[int], t: dict[str, float], serial: bool) -> None:
            members = [(self._scorer_of[geos[i][0]], geos[i][1]) for i in job]
            for i, dec in zip(job, group_band_scores(frame, members, t, serial, spans[job[0]], padded)):
                results[i] = dec

        if n_threads < 2 or len(jobs) < 2:
            for job in jobs:
                score(job, timings, False)
            return results
        helpers = n_threads - 1  # the calling thread takes jobs too
        with self._pool_lock:
            if self._pool is None or self._pool_size != helpers:
                if self._pool is not None:
                    self._pool.shutdown(wait=False)
                self._pool = ThreadPoolExecutor(max_workers=helpers, thread_name_prefix="fastdet-band")
                self._pool_size = helpers
            pool = self._pool

        def work(job: list[int]) -> int:
            g, sp = geos[job[0]][1], spans[job[0]]
            cols = g.nx if sp is None else sum(max(0, min(j1, g.nx) - max(j0, 0)) for j0, j1 in sp)
            return g.scaled_h * cols * len(job)

        # biggest jobs first, so the last one to finish is a small one; every thread takes the
        # next job when it is done with one
        order = sorted(range(len(jobs)), key=lambda k: -work(jobs[k]))
        times: list[dict[str, float]] = [{} for _ in jobs]
        lock = threading.Lock()
        nxt = [0]

        def run() -> None:
            with serial_kernels():  # this thread runs the serial kernels
                while True:
                    with lock:
                        if nxt[0] >= len(order):
                            return
                        k = order[nxt[0]]
                        nxt[0] += 1
                    score(jobs[k], times[k], True)

        futures = [pool.submit(run) for _ in range(helpers)]
        run()
        for f in futures:
            f.result()
        for t in times:
            for key, v in t.items():
                timings[key] = timings.get(key, 0.0) + v
        return results

    @staticmethod
    def _needs_pixels(geo: BandGeometry, spans: Sequence[tuple[int, int]] | None) -> bool:
        """Whether :meth:`_Scorer.band_scores` will cut the band (some window to score)."""
        return spans is None or any(min(j1, geo.nx) > max(j0, 0) for j0, j1 in spans)

    def close(self) -> None:
        """Stop the band threads (also done when the Detector is garbage-collected)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool, self._pool_size = None, 0

    def __del__(self) -> None:
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.shutdown(wait=False)

    def geometries(self, frame_shape: tuple[int, int], part: int = 0) -> list[BandGeometry]:
        """Geometry of every search band of model ``part`` on a frame of ``(H, W)``."""
        return self._scorer_of[part].geometries(frame_shape)

    def main_geometries(self, frame_shape: tuple[int, int]) -> list[tuple[int, BandGeometry]]:
        """``(part, geometry)`` of every band of the main model and then of each component
        (:attr:`main_parts`), in the order :meth:`detect`'s ``columns`` refer to them."""
        return [(p, g) for p in self.main_parts for g in self._scorer_of[p].geometries(frame_shape)]

    def band_columns(self, columns: Sequence[Sequence[tuple[int, int]] | None] | None,
                     frame_shape: tuple[int, int]) -> list[Sequence[tuple[int, int]] | None] | None:
        """``columns`` (as :meth:`detect` takes them) with one entry per band of
        :meth:`main_geometries`: those given; then each component band not given takes the entry
        of the main model's band with the same pixels and windows across (its twin: a side-view
        component searches the main model's bands, with its features), so a guided search that
        plans the main model's bands plans the component's alike; any other band ``None`` (all its
        windows)."""
        if columns is None:
            return None
        geos = self.main_geometries(frame_shape)
        out: list[Sequence[tuple[int, int]] | None] = list(columns) + [None] * (len(geos) - len(columns))
        main_features = self._scorer_of[MAIN_PART].feature_key
        twin = {image_key(g): j for j, (p, g) in enumerate(geos[:len(columns)]) if p == MAIN_PART}
        for j in range(len(columns), len(geos)):
            if self._scorer_of[geos[j][0]].feature_key != main_features:
                continue  # another cell or window width: the main band's columns are other pixels
            t = twin.get(image_key(geos[j][1]))
            if t is not None:
                out[j] = columns[t]
        return out

    def detect(self, frame: np.ndarray, rgb: bool = False,
               oncoming_bands: Sequence[SearchBand] | None = None, stats: DetectStats | None = None,
               columns: Sequence[Sequence[tuple[int, int]] | None] | None = None) -> Detections:
        """Positive windows of one frame.

        frame: ``(H, W, 3) uint8``, BGR (OpenCV's order) or RGB with ``rgb=True``.
        oncoming_bands: bands (in this frame's pixels) for the oncoming model to search instead of
            its own search's; an empty list skips it. :class:`fastdet.VideoDetector` passes
            the parts of the oncoming search where the picture moves (:mod:`fastdet.video.motion`).
        stats: a :class:`DetectStats` to record stage times and every band's decision values
            into (optional).
        columns: which windows of the main model's and the components' bands to score, one
            entry per band of :meth:`main_geometries` (missing entries: :meth:`band_columns`):
            ``None`` for all, else a sequence of window-column ranges ``(j0, j1)``,
            ``j0 <= j < j1``. Each scored window's decision value is the one the whole band
            gives it (to rounding, ~1e-15): the band is cut and resized as a whole, HOG runs on
            a slice of it with a window step of margin. Windows not scored are negative (-inf in ``stats``).
            :class:`fastdet.VideoDetector` searches near the tracked vehicles this way
            between full scans (:class:`fastdet.config.GuidedSearch`).
        Returns :class:`~fastdet.detections.Detections` with columns ``boxes (N, 4) int32``
        x1, y1, x2, y2 (exclusive) in frame pixels, ``scores (N,) float32`` (the probability of
        "vehicle" for logistic-regression models, the decision value for LinearSVC; both
        models have the same kind), ``scale`` (the window's band scale) and ``part``
        (``MAIN_PART``, ``ONCOMING_PART``, or ``FIRST_COMPONENT_PART + i`` for component ``i``).
        A window is positive when its decision value
        exceeds its model's ``search.threshold``.
        """
        frame = np.asarray(frame)
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.dtype} {frame.shape}")
        if rgb:
            frame = frame[:, :, ::-1]
        timings: dict[str, float] = stats.timings if stats is not None else {}
        geos = self.main_geometries(frame.shape[:2])
        if columns is not None and len(columns) > len(geos):
            raise ValueError(f"columns: {len(columns)} entries for {len(geos)} bands")
        columns = self.band_columns(columns, frame.shape[:2])
        if self.oncoming_model is not None:
            sc = self._scorer_of[ONCOMING_PART]
            if oncoming_bands is None:
                geos += [(ONCOMING_PART, g) for g in sc.geometries(frame.shape[:2])]
            else:
                geos += [(ONCOMING_PART, band_geometry(b, frame.shape[:2], sc.config, sc.search.cells_per_step))
                         for b in oncoming_bands]
        bands = [(part, geo, dec) for (part, geo), dec in zip(geos, self._all_band_scores(frame, geos, timings,
                                                                                          columns))]
        if stats is not None:
            stats.bands.extend(bands)
        return self.windows(bands)

    def windows(self, bands: Sequence[tuple[int, BandGeometry, np.ndarray]]) -> Detections:
        """The positive windows of band decision values, as :meth:`detect` returns them: ``bands``
        holds ``(part, geometry, decision values (geo.ny, geo.nx) float64)`` (as
        :attr:`DetectStats.bands`; -inf: not scored), a window is positive when its value exceeds
        its model's ``search.threshold`` (a stricter one on a band's slack rows:
        :func:`~fastdet.detect.geometry.row_thresholds`), its score is its decision value or, for
        logistic-regression models, its probability."""
        boxes, decs, scales, parts = [], [], [], []
        for part, geo, dec in bands:
            sc = self._scorer_of[part]
            thr = sc.row_thresholds(geo)  # a band's slack rows: a higher threshold
            r, c = np.nonzero(dec > (thr[:, None] if isinstance(thr, np.ndarray) else thr))
            if len(r):
                boxes.append(window_boxes(geo, r, c, sc.config))
                decs.append(dec[r, c])
                scales.append(np.full(len(r), geo.band.scale, np.float32))
                parts.append(np.full(len(r), part, np.int8))
        if not boxes:
            return Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32),
                              scale=np.zeros(0, np.float32), part=np.zeros(0, np.int8))
        score = np.concatenate(decs)  # float64 decision values
        if self.score_kind == "probability":
            score = 1.0 / (1.0 + np.exp(-score))
        return Detections(np.concatenate(boxes), score.astype(np.float32),
                          scale=np.concatenate(scales), part=np.concatenate(parts))

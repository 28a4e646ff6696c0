"""The main model's operating point set from the video itself, with no label.

A linear window classifier's decision values move with the camera: on footage it was not built
on, a model may give most of the picture's windows higher values (it fires on background: more
false windows) or lower ones (its windows on small vehicles never reach the threshold). Almost
every window the full search scores is background, so where the bulk of a video's decision values
lies says how permissive the model is on this camera. :class:`SelfCalStage` takes the decision
values of every main-model window of the video's first full scans
(:attr:`SelfCalibration.scans <fastdet.config.SelfCalibration>`), finds the value ``q`` that a
fraction :attr:`~fastdet.config.SelfCalibration.rate` of them exceeds
(:func:`calibration_offset`) and from then on subtracts ``q - level`` from every decision value of
the main model (:meth:`fastdet.Detector.set_decision_offset`): every threshold the pipeline
applies to a main-model window moves with it. No window is scored that the pipeline would not
score: for a file, the first full scans are scored ahead from the frames the horizon is
estimated from (:meth:`SelfCalStage.tee` / :meth:`SelfCalStage.prime`, through
:meth:`fastdet.VideoDetector.prime_horizon`), so every frame runs at the estimated offset; for a
live source, the run's own first full scans give it and it applies after them. A cut keeps it (the
camera stays), as it keeps the horizon. What it gave on the annotated clips: docs/training.md
("Operating point from the video itself").
"""
from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from ..config import SelfCalibration
from ..detections import MAIN_PART
from .detector import DecisionOffset
from .state import FrameState, Stage


def calibration_offset(values: np.ndarray, config: SelfCalibration, current: float = 0.0) -> float:
    """The decision offset for a model whose windows scored ``values`` (decision values with an
    offset ``current`` already subtracted, any shape; non-finite ones -- windows not scored --
    are left out): ``q - level`` clipped to ``[-max_shift, max_shift]``, where ``q`` is the
    model's own decision value (``values + current``) that a fraction ``rate`` of the windows
    exceeds (the ``1 - rate`` quantile, linear between the values either side). ``ValueError``
    for no finite value."""
    v = np.asarray(values, np.float64).ravel()
    v = v[np.isfinite(v)]
    if not len(v):
        raise ValueError("calibration_offset: no scored window")
    q = float(np.quantile(v, 1.0 - config.rate)) + float(current)
    return float(np.clip(q - config.level, -config.max_shift, config.max_shift))


class SelfCalStage(Stage):
    """Sets the main model's decision offset of ``detector`` from the first ``config.scans``
    full scans of the video (module docstring); ``every``: frames between full scans (the
    guided search's :attr:`~fastdet.config.GuidedSearch.every`, 1 for the full search on every
    frame), which frames :meth:`prime` scores ahead. After :meth:`prime` or the run's own
    ``scans`` full scans, ``offset`` is the offset in force (``None`` before)."""

    name = "selfcal"

    def __init__(self, detector: DecisionOffset, config: SelfCalibration, every: int = 1) -> None:
        if not isinstance(detector, DecisionOffset):
            raise TypeError(f"the self-calibration needs a detector whose decision values can move "
                            f"(set_decision_offset, band_scores), got {type(detector).__name__}")
        if int(every) != every or every < 1:
            raise ValueError(f"every must be an integer >= 1, got {every!r}")
        self.detector, self.config, self.every = detector, config, int(every)
        self.offset: float | None = None
        self.scans = 0  # full scans taken so far
        self._values: list[np.ndarray] = []
        self._kept: list[np.ndarray] = []  # frames to score ahead (prime)
        self._index = 0  # frames seen by tee / prime
        self._base = detector.decision_offset  # the offset the values are scored with

    @property
    def done(self) -> bool:
        return self.offset is not None

    def _see(self, frame: np.ndarray) -> None:
        """Count one of the video's first frames; keep a copy if the run would full-scan it and
        the estimate still wants it."""
        if not self.done and self._index % self.every == 0 and len(self._kept) < self.config.scans:
            self._kept.append(np.array(frame, copy=True))
        self._index += 1

    def tee(self, frames: Iterator[np.ndarray]) -> Iterator[np.ndarray]:
        """``frames`` (the video's first, BGR) passed on; those the run would full-scan kept for :meth:`prime`."""
        for f in frames:
            self._see(f)
            yield f

    def prime(self, frames: Iterator[np.ndarray]) -> float | None:
        """Read on from ``frames`` (the video's first frames after those :meth:`tee` saw, BGR)
        until ``scans`` full-scan frames are kept, score them with the detector's main bands as
        they are now (call it once the horizon is set) and set the offset; with fewer frames
        than that, the ones there are. Returns the offset (``None``: no frame)."""
        if self.done:
            return self.offset
        if len(self._kept) < self.config.scans:
            for f in frames:
                self._see(f)
                if len(self._kept) >= self.config.scans:
                    break
        det = self.detector
        for f in self._kept:
            for geo in det.geometries(f.shape[:2], 0):  # type: ignore[attr-defined]
                self._add(det.band_scores(f, geo))
            self.scans += 1
        self._kept = []
        if self._values:
            self._settle()
        return self.offset

    def _add(self, dec: np.ndarray) -> None:
        v = np.asarray(dec, np.float64).ravel()
        self._values.append(v[np.isfinite(v)])

    def _settle(self) -> None:
        delta = calibration_offset(np.concatenate(self._values), self.config, self._base)
        self.detector.set_decision_offset(delta)
        self.offset = delta
        self._values = []

    def __call__(self, s: FrameState) -> FrameState:
        if self.done or s.columns is not None or s.bands is None:
            return s  # settled, or not a full scan of the main bands
        for part, _geo, dec in s.bands:
            if part == MAIN_PART:
                self._add(dec)
        self.scans += 1
        if self.scans >= self.config.scans:
            self._settle()  # from the next frame on
        return s

    def reset(self) -> None:
        """A cut: the camera stays, so does the offset (an estimate under way goes on)."""

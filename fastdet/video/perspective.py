"""The camera's perspective learnt from the video's own vehicles: the main search's bands
follow the horizon and the ratio the tracked vehicles show. No stage of the pipeline runs it
(the ``perspective`` stage was deleted: docs/accuracy.md, "Deleted stages"); what drives it is
``tools/studies/geometry_study.py --joint``, frame by frame over the pipeline's tracked boxes.

Until the video has shown a vehicle, the main search is :class:`~fastdet.detect.geometry.GeometricSearch`
at the prior: the horizon as the rest of the pipeline has it (the flow estimate,
:mod:`fastdet.video.horizon`, or the user's ``--horizon``), the prior ratio, and a slack of
``slack`` x the frame height above and below every band, so a horizon that is off by that
much still finds the first vehicles. Every frame, the tracked boxes whose score is at least
``min_score`` feed a :class:`~fastdet.detect.geometry.PerspectiveEstimator`; once it has an
estimate (``min_tracks`` tracks of ``min_boxes`` boxes), the bands move to its horizon and
ratio and the slack drops to ``settled_slack``.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config import PerspectiveConfig, SearchConfig
from ..detect.geometry import GeometricSearch, PerspectiveEstimator
from ..detections import Detections


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


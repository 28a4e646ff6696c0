"""The slack rows' thresholds of a search band: a window that reaches into the rows a band
searches beyond its own (:attr:`~fastdet.config.SearchBand.slack_above`, placed by
:meth:`~fastdet.config.SearchConfig.for_frame`) must beat the
search's ``slack_threshold`` (docs/geometry.md). (Bands placed from the camera's geometry and
the perspective estimated from the tracked vehicles, once here, are study code now:
``tools/studies/perspective.py``.)
"""
from __future__ import annotations

import numpy as np

from ..config import FeatureConfig, SearchConfig
from .bands import BandGeometry, window_boxes


def row_thresholds(geo: BandGeometry, search: SearchConfig, config: FeatureConfig) -> np.ndarray | float:
    """The decision value each window row of the band ``geo`` must exceed to be positive:
    ``search.threshold`` where the window lies inside the band's core rows
    (:attr:`~fastdet.config.SearchBand.core`), ``search.slack_threshold`` where it reaches
    into the slack above or below them (a ``(geo.ny,)`` array); the plain ``search.threshold``
    (a float) for a band without slack or a search without a slack threshold."""
    core, gate = geo.band.core, search.slack_threshold
    if core is None or gate is None or geo.ny == 0:
        return float(search.threshold)
    rows = np.arange(geo.ny)
    b = window_boxes(geo, rows, np.zeros(geo.ny, np.int64), config)
    inside = (b[:, 1] >= core[0] - 1) & (b[:, 3] <= core[1] + 1)  # to the rounding of a band's rows
    return np.where(inside, float(search.threshold), float(gate))

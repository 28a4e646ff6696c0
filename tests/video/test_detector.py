"""fastdet/video/detector.py: make_detector builds the detector a PipelineConfig asks for (which
abilities pick which stages: tests/video/test_stages.py)."""
from __future__ import annotations

import pytest

from fastdet.config import PipelineConfig, oncoming_search
from fastdet.video import make_detector


def test_make_detector_puts_the_oncoming_search_on_the_side_traffic_comes_from():
    for side in ("right", "left", "both"):
        det = make_detector(PipelineConfig(traffic=side))
        assert det.scorers[1].search == oncoming_search(side)
    assert make_detector().scorers[1].search == oncoming_search("right")
    left = make_detector(PipelineConfig(traffic="left")).scorers[1].search.bands
    right = make_detector(PipelineConfig(traffic="right")).scorers[1].search.bands
    assert left != right
    with pytest.raises(ValueError, match="traffic"):
        make_detector(PipelineConfig(traffic="middle"))  # type: ignore[arg-type]

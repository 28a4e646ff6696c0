"""fastdet.config.perspective: the geometry and perspective settings check their values and
round-trip through JSON."""
from __future__ import annotations

import pytest

from fastdet.config import GeometryConfig, PerspectiveConfig


@pytest.mark.parametrize("kw, words", [
    ({"ratio": 0}, "ratio"), ({"reference_ratio": -1}, "ratio"), ({"slack": 1.0}, "slack"), ({"slack": -0.1}, "slack"),
])
def test_geometry_checks(kw, words):
    with pytest.raises(ValueError, match=words):
        GeometryConfig(**kw)


@pytest.mark.parametrize("kw", [{"settled_slack": 1.0}, {"min_tracks": 0}, {"min_boxes": 0}, {"sigma_h": 0},
                                {"sigma_ratio": 0}, {"prior_frames": -1}])
def test_perspective_checks(kw):
    with pytest.raises(ValueError):
        PerspectiveConfig(**kw)


def test_round_trip():
    c = PerspectiveConfig(geometry=GeometryConfig(ratio=2.2, slack=0.03), prior_frames=50, long_track=30)
    assert PerspectiveConfig.from_dict(c.to_dict()) == c
    assert PerspectiveConfig().geometry == GeometryConfig()

"""fastdet/config/track.py: TrackerConfig's checks and round trip (the tracker it configures:
tests/video/test_track.py)."""
from __future__ import annotations

import pytest

from fastdet.config import TrackerConfig


def test_tracker_config_is_checked():
    with pytest.raises(ValueError):
        TrackerConfig(low_heat=1.5)
    with pytest.raises(ValueError):
        TrackerConfig(min_hits=0)
    with pytest.raises(ValueError):
        TrackerConfig(output="kalman")
    with pytest.raises(ValueError):
        TrackerConfig(hold_row=1)
    for bad in (-0.1, 1.0, 1.5):
        with pytest.raises(ValueError):
            TrackerConfig(exit_outside=bad)
    for bad in (0, 1.5):
        with pytest.raises(ValueError):
            TrackerConfig(exit_after=bad)
    # the deleted queue gate, shape test and extension back: a dict holding their off values
    # still loads, others are refused
    assert TrackerConfig.from_dict({"max_behind": None, "behind_speed": 0.1, "cut_shape": None,
                                    "extend_back": 0}) == TrackerConfig()
    for on in ({"max_behind": 0.5}, {"extend_back": 1}):
        with pytest.raises(ValueError, match="deleted"):
            TrackerConfig.from_dict(on)
    assert "extend_back" not in TrackerConfig().to_dict() and TrackerConfig().digest_dict()["extend_back"] == 0
    assert TrackerConfig.from_dict(TrackerConfig().to_dict()) == TrackerConfig()

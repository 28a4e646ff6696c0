"""fastdet/config/motion.py: MotionGate's checks, round trip, and the frame lag at a frame rate
(the gate itself: tests/video/test_motion.py, test_motion_rate.py)."""
from __future__ import annotations

import pytest

from fastdet.config import MotionGate


@pytest.mark.parametrize("v", [-1.0, 256.0, float("nan")])
def test_motion_gate_refuses(v):
    with pytest.raises(ValueError, match="min_motion"):
        MotionGate(v)


def test_motion_gate_validates():
    assert MotionGate().min_motion == 45.0
    assert MotionGate.from_dict(MotionGate(30).to_dict()) == MotionGate(30)
    for bad in (-1, 256, float("nan")):
        with pytest.raises(ValueError):
            MotionGate(bad)


@pytest.mark.parametrize("fps, lag", [(None, 1), (25.0, 1), (29.97, 1), (12.5, 1), (50.0, 2), (59.94, 2),
                                      (100.0, 4)])
def test_lag_follows_the_frame_rate(fps, lag):
    assert MotionGate().lag(fps) == lag

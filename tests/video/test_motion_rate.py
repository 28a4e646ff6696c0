"""The motion gate and the frame rate (issue 14, item 9): frames are compared 1/25 s apart
whatever the video's rate, so a 50 fps video (or one with every frame doubled) is judged
on the same motion as the 25 fps footage the gate was measured on."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet import VideoDetector
from fastdet.config import MotionGate
from fastdet.video import make_detector
from fastdet.video import motion as motion_mod
from fastdet.video.motion import FrameMotion, window_motion


def _moving(n: int) -> list[np.ndarray]:
    out = []
    for i in range(n):
        f = np.zeros((60, 200, 3), np.uint8)
        f[20:40, 10 + 8 * i: 40 + 8 * i] = 200
        out.append(f)
    return out


def test_doubled_frames_with_lag_2_move_as_the_original():
    frames = _moving(6)
    doubled = [f for f in frames for _ in (0, 1)]
    box = np.array([[0, 0, 200, 60]])
    one = FrameMotion()
    orig = [m for f in frames if (m := one.update(f)) is not None]
    lag1, lag2 = FrameMotion(), FrameMotion()
    m1 = [m for f in doubled if (m := lag1.update(f)) is not None]
    m2 = [m for f in doubled if (m := lag2.update(f, lag=2)) is not None]
    assert min(window_motion(m, box)[0] for m in m1) == 0  # every other pair is the same picture
    want = window_motion(orig[0], box)[0]
    assert want > 0 and all(window_motion(m, box)[0] == pytest.approx(want) for m in m2)


def test_video_detector_compares_frames_by_its_fps(monkeypatch):
    lags = []
    real = motion_mod.FrameMotion.update

    def spy(self, frame, roi=None, lag=1):
        lags.append(lag)
        return real(self, frame, roi, lag)

    monkeypatch.setattr(motion_mod.FrameMotion, "update", spy)
    det = make_detector()
    frame = np.zeros((720, 1280, 3), np.uint8)
    for fps, want in ((50.0, 2), (25.0, 1), (None, 1)):
        lags.clear()
        vd = VideoDetector(det, fps=fps)
        vd.update(frame)
        vd.update(frame)
        assert lags == [want, want]


def test_noise_relative_gate_is_optional():
    assert MotionGate().threshold(20.0) == 45.0  # default: absolute
    assert MotionGate(noise_factor=6).threshold(10.0) == 60.0
    assert MotionGate(noise_factor=6).threshold(2.0) == 45.0
    assert MotionGate(min_motion=0, noise_factor=6).threshold(10.0) == 0.0  # gate off
    m = FrameMotion()
    m.update(np.zeros((8, 8, 3), np.uint8))
    assert m.update(np.full((8, 8, 3), 7, np.uint8)).noise == 7.0
    with pytest.raises(ValueError):
        MotionGate(reference_fps=0)

"""fastdet/video/state.py: FrameDebug, the record of what one frame went through, new every
frame and cleared by reset (FrameState through the stages: tests/video/test_stages.py)."""
from __future__ import annotations

import numpy as np

from fastdet.config import PipelineConfig
from fastdet.video import FrameDebug, VideoDetector
from tests.fakes import SquareDetector


def frame() -> np.ndarray:
    f = np.zeros((360, 640, 3), np.uint8)
    f[100:160, 200:280] = 255
    return f


def test_frame_debug_is_a_new_record_every_frame_and_reset_clears_it():
    vd = VideoDetector(SquareDetector(), PipelineConfig(refine=None, heat=PipelineConfig().heat.single_frame(1.0)))
    assert isinstance(vd.debug, FrameDebug) and len(vd.debug.windows) == 0
    out = vd.update(frame())
    first = vd.debug
    assert len(first.windows) == 3 and first.heat.shape == (90, 160) and first.mask.any()
    assert first.labels.max() == 1 and len(first.boxes) == 1
    assert [t[:2] for t in first.tracks] == [(1, "tracked")] and out.ids.tolist() == [1]
    vd.update(frame())
    assert vd.debug is not first and len(first.windows) == 3
    vd.reset()
    assert len(vd.debug.windows) == 0 and vd.debug.heat.shape == (0, 0)

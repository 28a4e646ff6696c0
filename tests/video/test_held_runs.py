"""The pipeline over a file's held frames (fastdet.io.held, as ``adapt``'s operating point feeds
its three runs) gives exactly the boxes, scores and ids of the file re-opened at the stretch:
a pipeline run and the replay of the offsets, on a real clip's last frames (fewer than the
horizon's read-ahead: the frames ahead come from the held ones too)."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.io.hold import hold_frames
from fastdet.video.horizon import HORIZON_FRAMES
from fastdet.video.replay import iter_offset_detections
from fastdet.video.run import iter_video_detections

START, FRAMES = 78, 10  # test_small1's last 10 frames (88 decode)


@pytest.fixture(scope="module")
def clip(data):
    return str(data / "videos" / "test_small1.mp4")


def _equal(a, b) -> None:
    assert [f for f, _ in a] == [f for f, _ in b] and len(a) == FRAMES
    for (fno, x), (_, y) in zip(a, b):
        assert np.array_equal(x.boxes, y.boxes) and np.array_equal(x.scores, y.scores), fno
        assert (x.ids is None and y.ids is None) or np.array_equal(x.ids, y.ids), fno


@pytest.mark.parametrize("spill", [False, True])
def test_runs_over_held_frames_are_those_over_the_file(clip, tmp_path, spill):
    held = hold_frames(clip, START, max(FRAMES, HORIZON_FRAMES), max_bytes=0 if spill else None, spill_dir=tmp_path,
                       notify=lambda _n: None)
    try:
        assert held.ended and (held.spill is not None) == spill
        if not spill:  # one pipeline run is enough to tell the two sources apart; the replay on one of them
            want = list(iter_video_detections(clip, start=START, frames=FRAMES, progress=False))
            _equal(list(iter_video_detections(held, start=START, frames=FRAMES, progress=False)), want)
            assert sum(len(d) for _, d in want) > 0
        else:
            offs = (3.0,)
            want_o = list(iter_offset_detections(clip, offs, start=START, frames=FRAMES))
            got_o = list(iter_offset_detections(held, offs, start=START, frames=FRAMES))
            for o in offs:
                _equal([(f, d[o]) for f, d in got_o], [(f, d[o]) for f, d in want_o])
    finally:
        held.close()
    assert not list(tmp_path.iterdir())

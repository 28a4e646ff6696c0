"""VideoDetector.start and run_frames: a frame's last stages (refinement, plausibility) on a
background thread beside the next frame's first give exactly what update() gives."""
from __future__ import annotations

import threading

import numpy as np
import pytest

from fastdet.io.reader import FrameReader
from fastdet.video import VideoDetector
from fastdet.video.pipeline import run_frames
from fastdet.video.stages import TAIL_STAGES, RefineStage


def _table(dets) -> tuple:
    return (dets.boxes.tolist(), dets.scores.tolist(), None if dets.ids is None else dets.ids.tolist())


def test_beside_gives_update_s_boxes_ids_debug_and_timings_on_a_real_clip(data):
    """10 frames of test_small1 (1280x720, the bundled models, every stage on): each frame's
    boxes, scores, ids and debug record equal a plain update() loop's, and the timings name the
    same stages."""
    path = data / "videos" / "test_small1.mp4"
    plain, ahead = VideoDetector(), VideoDetector()
    assert [type(s) for s in plain.stages[-2:]] == list(TAIL_STAGES)
    with FrameReader(path, 0, 10) as reader:
        frames = list(reader)
    want, debugs, keys = [], [], []
    for _, frame, _ in frames:
        want.append(_table(plain.update(frame)))
        debugs.append(plain.debug)
        keys.append(set(plain.timings))
    got = []
    for i, (fno, frame, _, dets) in enumerate(run_frames(ahead, frames, beside=True)):
        assert fno == frames[i][0] and frame is frames[i][1]
        got.append(_table(dets))
        assert ahead.debug.boxes.boxes.tolist() == debugs[i].boxes.boxes.tolist()
        assert np.array_equal(ahead.debug.heat, debugs[i].heat)
        assert set(ahead.timings) == keys[i] and {"refine", "plausible"} <= keys[i]
    assert got == want
    assert sum(len(b) for b, _, _ in want) > 5  # vehicles were found and refined
    ahead.close()


class _Slow(RefineStage):
    """A refinement stage that, from its second frame on, waits for ``gate``; it records each
    frame it finished."""

    def __init__(self, gate: threading.Event, ran: list[int]) -> None:
        self.gate, self.ran = gate, ran

    def __call__(self, s):
        if self.ran:
            assert self.gate.wait(10)
        self.ran.append(1)
        return s


def _frames(n: int):
    return [(i + 1, np.zeros((120, 160, 3), np.uint8), 0.0) for i in range(n)]


def test_stopping_early_waits_for_the_frame_in_flight():
    vd = VideoDetector(config=None)
    gate, ran = threading.Event(), []
    stages = vd.stages
    stages[stages.index(vd.stage(RefineStage))] = _Slow(gate, ran)
    gen = run_frames(vd, _frames(3), beside=True)
    first = next(gen)  # frame 2 has begun: its refinement waits on the gate
    assert first[0] == 1 and ran == [1]
    closer = threading.Thread(target=gen.close)
    closer.start()
    closer.join(0.5)
    assert closer.is_alive()  # close() waits for frame 2's last stages
    gate.set()
    closer.join(10)
    assert not closer.is_alive() and len(ran) == 2
    vd.close()


def test_an_error_in_the_last_stages_comes_out_of_the_frame_s_result():
    vd = VideoDetector()

    class Broken(RefineStage):
        def __init__(self) -> None:
            pass

        def __call__(self, s):
            raise RuntimeError("refine broke")

    stages = vd.stages
    stages[stages.index(vd.stage(RefineStage))] = Broken()
    pending = vd.start(np.zeros((120, 160, 3), np.uint8), beside=True)
    with pytest.raises(RuntimeError, match="refine broke"):
        pending.result()
    vd.close()


def test_a_reading_error_comes_after_the_frame_before_it():
    def frames():
        yield from _frames(2)
        raise OSError("decode failed")

    vd = VideoDetector()
    got = []
    with pytest.raises(OSError, match="decode failed"):
        for fno, _, _, _ in run_frames(vd, frames(), beside=True):
            got.append(fno)
    assert got == [1, 2]
    vd.close()

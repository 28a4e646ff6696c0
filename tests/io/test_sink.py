"""fastdet.io.sink: the annotated video keeps every pixel of the frames; no wait for its encoder
is unbounded."""
from __future__ import annotations

import signal
import threading
import time

import cv2
import numpy as np
import pytest

from fastdet import signals
from fastdet.detections import Detections
from fastdet.errors import WriteError
from fastdet.io import sink as sink_mod
from fastdet.io.sink import VideoSink


def test_odd_frame_size_is_padded_not_cut(tmp_path):
    """MPEG-4 has even sizes: FFmpeg silently cut 1281x719 to 1280x718. The sink adds one
    black column / row instead, and says so."""
    notes: list[str] = []
    out = tmp_path / "o.mp4"
    yy, xx = np.mgrid[0:361, 0:641]
    frame = np.ascontiguousarray(np.stack([xx * 255 // 640, yy * 255 // 360, 128 + 0 * xx], -1).astype(np.uint8))
    sink = VideoSink(str(out), 25.0, (641, 361), notify=notes.append)
    for _ in range(3):
        sink.put((frame.copy(), Detections.empty(), None))
    assert sink.close() == out
    assert len(notes) == 1 and "641x361 are written as 642x362" in notes[0]
    cap = cv2.VideoCapture(str(out))
    ok, got = cap.read()
    cap.release()
    assert ok and got.shape == (362, 642, 3)
    # the last column and row of the picture are there (lossy: close, not equal)
    grey = cv2.cvtColor(got, cv2.COLOR_BGR2GRAY).astype(int)
    want = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY).astype(int)
    assert np.abs(grey[:361, 640] - want[:, 640]).mean() < 12 and np.abs(grey[360, :641] - want[360]).mean() < 12
    assert grey[:, 641].mean() < 40 and grey[361].mean() < 40  # the added column and row: black


def test_even_frame_size_has_no_note(tmp_path):
    notes: list[str] = []
    sink = VideoSink(str(tmp_path / "o.mp4"), 25.0, (64, 48), notify=notes.append)
    sink.put((np.zeros((48, 64, 3), np.uint8), Detections.empty(), None))
    sink.close()
    assert notes == []


# ------------------------------------------------------------------ a stuck or slow encoder


class _Writer:
    """Stands in for the sink's ``cv2.VideoWriter``: each ``write`` waits for ``gate`` (an
    encoder stuck inside OpenCV, e.g. on a disk that stopped answering) or sleeps ``delay``
    seconds (a slow one), then writes."""

    def __init__(self, real, gate: threading.Event | None = None, delay: float = 0.0) -> None:
        self.real, self.gate, self.delay = real, gate, delay

    def write(self, frame) -> None:
        if self.gate is not None:
            self.gate.wait()
        time.sleep(self.delay)
        self.real.write(frame)

    def release(self) -> None:
        self.real.release()


@pytest.fixture
def sinks(monkeypatch):
    """``make(path, stall_s=..., stuck=..., delay=...)``: a 64x48 sink with a queue of 2 frames
    whose encoder is stuck (until the test ends) or slow. At the end the stuck writes are let
    go and every encoder thread is waited for: no thread is left blocked."""
    monkeypatch.setattr(sink_mod, "QUEUE_SIZE", 2)
    gate = threading.Event()
    made: list[VideoSink] = []

    def make(path, stuck: bool = False, delay: float = 0.0, **kw) -> VideoSink:
        sink = VideoSink(str(path), 25.0, (64, 48), **kw)
        sink._writer = _Writer(sink._writer, gate if stuck else None, delay)
        made.append(sink)
        return sink

    yield make
    gate.set()
    for sink in made:
        sink.close(discard=True)  # a no-op when closed; else the encoder is told to end
        sink._thread.join(10)
        assert not sink._thread.is_alive()


def _within(seconds: float, fn):
    """``fn()`` in a thread, given ``seconds``: ``(its exception or None, seconds taken)``; the
    test fails, instead of hanging, when it has not returned by then."""
    out: list = []

    def run() -> None:
        try:
            fn()
            out.append(None)
        except BaseException as exc:  # handed to the test
            out.append(exc)

    t0 = time.monotonic()
    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"still waiting after {seconds} s"
    return out[0], time.monotonic() - t0


def _item():
    return np.zeros((48, 64, 3), np.uint8), Detections.empty(), None


def test_put_gives_up_on_a_stuck_encoder(sinks, tmp_path):
    """``put`` waited without a bound for an encoder stuck inside OpenCV (in the frame loop's
    patient block, where no signal stops it). Now ``WriteError`` once it has written nothing
    for the stall limit; no file under the final name."""
    out = tmp_path / "o.mp4"
    sink = sinks(out, stuck=True, stall_s=0.3)

    def fill() -> None:
        for _ in range(50):
            sink.put(_item())

    exc, took = _within(10, fill)
    assert isinstance(exc, WriteError) and 0.3 <= took < 5, (exc, took)
    assert str(out) in str(exc) and "has written nothing for 0.3 s" in str(exc)
    exc, took = _within(10, sink.close)
    assert isinstance(exc, WriteError) and took < 1, (exc, took)  # no second wait
    assert not out.exists() and not sink.tmp.exists()


def test_close_gives_up_on_a_stuck_encoder(sinks, tmp_path):
    """``close`` joined the encoder thread without a bound. Now ``WriteError`` once it has
    written nothing for the stall limit: the temporary file removed, no file under the final
    name, the thread left behind."""
    out = tmp_path / "o.mp4"
    sink = sinks(out, stuck=True, stall_s=0.3)
    sink.put(_item())
    exc, took = _within(10, sink.close)
    assert isinstance(exc, WriteError) and 0.3 <= took < 5, (exc, took)
    assert "has written nothing for" in str(exc)
    assert not out.exists() and not sink.tmp.exists()
    assert sink._thread.is_alive()  # left behind: let go at the end of the test
    assert sink.close() is None and sink.close(discard=True) is None


def test_close_discard_does_not_wait_for_a_stuck_encoder(sinks, tmp_path):
    """Discarding has nothing to finish: at most ``DISCARD_WAIT_S``, not the stall limit."""
    out = tmp_path / "o.mp4"
    sink = sinks(out, stuck=True)  # the default stall limit (60 s)
    for _ in range(3):
        sink.put(_item())
    exc, took = _within(10, lambda: sink.close(discard=True))
    assert exc is None and took < sink_mod.DISCARD_WAIT_S + 1, took
    assert not out.exists() and not sink.tmp.exists()


def test_a_stop_ends_the_wait_for_a_stuck_encoder_soon(sinks, tmp_path, monkeypatch):
    """Once a stop signal came, ``put`` gives up after ``STOP_STALL_S``, not the stall limit."""
    monkeypatch.setattr(sink_mod, "STOP_STALL_S", 0.3)
    monkeypatch.setattr(signals, "_received", signal.SIGINT)  # what the handler sets
    sink = sinks(tmp_path / "o.mp4", stuck=True)  # the default stall limit (60 s)

    def fill() -> None:
        for _ in range(50):
            sink.put(_item())

    exc, took = _within(10, fill)
    assert isinstance(exc, WriteError) and took < 5, (exc, took)


def test_a_slow_encoder_that_keeps_writing_is_not_given_up_on(sinks, tmp_path):
    """Each frame takes most of the stall limit: ``put`` and ``close`` wait, every frame is
    written and the video kept."""
    out = tmp_path / "o.mp4"
    sink = sinks(out, delay=0.3, stall_s=0.5)

    def run() -> None:
        for _ in range(6):  # the queue holds 2: the later puts wait for the encoder
            sink.put(_item())
        assert sink.close() == out

    exc, _ = _within(30, run)
    assert exc is None, exc
    assert sink.frames == 6 and out.exists()
    cap = cv2.VideoCapture(str(out))
    n = cap.get(cv2.CAP_PROP_FRAME_COUNT)
    cap.release()
    assert n == 6

"""fastdet.io.sink: the annotated video keeps every pixel of the frames."""
from __future__ import annotations

import cv2
import numpy as np

from fastdet.detections import Detections
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

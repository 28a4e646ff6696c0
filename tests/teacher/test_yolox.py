"""fastdet.teacher.yolox against a slow, obvious reading of the teacher README: the letterbox
built pixel by pixel, the output decoded cell by cell and suppressed with a plain IoU loop,
on real frames of shared clips; and every model that is not a YOLOX-style detector refused
in one line."""
from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from fastdet.config import TeacherConfig
from fastdet.errors import FastdetError, ModelError
from fastdet.io.reader import read_frames_at
from tests.teacher.onnx_bytes import FLOAT, INT64, write_identity_model

pytest.importorskip("onnxruntime")

from fastdet.teacher import TeacherDetector  # noqa: E402
from fastdet.teacher.yolox import nms  # noqa: E402

VEHICLES = (2, 3, 5, 7)


@pytest.fixture(scope="module")
def model(yolox_nano: Path) -> Path:
    return yolox_nano


# ------------------------------------------------------------------ the slow reference


def slow_letterbox(frame: np.ndarray, height: int, width: int) -> tuple[np.ndarray, float]:
    """The README's input: the frame resized keeping its aspect to fit, grey 114 right and
    bottom, as (1, 3, H, W) float32 BGR 0..255."""
    import cv2

    fh, fw = frame.shape[:2]
    r = min(width / fw, height / fh)
    small = cv2.resize(frame, (int(fw * r), int(fh * r)), interpolation=cv2.INTER_LINEAR)
    blob = np.zeros((1, 3, height, width), np.float32)
    for c in range(3):
        plane = np.full((height, width), 114.0, np.float32)
        plane[: small.shape[0], : small.shape[1]] = small[:, :, c]
        blob[0, c] = plane
    return blob, r


def plain_iou(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    iw = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    ih = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = iw * ih
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def slow_decode(raw: np.ndarray, r: float, frame_hw: tuple[int, int], input_hw: tuple[int, int],
                min_score: float = 0.1, nms_iou: float = 0.45) -> list[tuple[float, float, float, float, float, int]]:
    """Every cell of every level, in the output's order, decoded on its own; then per class
    the greedy suppression, then the clip to the frame. ``[(x1, y1, x2, y2, score, class)]``."""
    H, W = input_hw
    fh, fw = frame_hw
    cands = []
    row = 0
    for s in (8, 16, 32):
        for gy in range(H // s):
            for gx in range(W // s):
                v = [float(x) for x in raw[0, row]]
                row += 1
                for c in VEHICLES:
                    score = v[4] * v[5 + c]
                    if score < min_score:
                        continue
                    cx, cy = (v[0] + gx) * s, (v[1] + gy) * s
                    w, h = math.exp(v[2]) * s, math.exp(v[3]) * s
                    box = ((cx - w / 2) / r, (cy - h / 2) / r, (cx + w / 2) / r, (cy + h / 2) / r)
                    cands.append((box, score, c))
    assert row == raw.shape[1]
    out = []
    for c in VEHICLES:
        mine = sorted([(b, s) for b, s, k in cands if k == c], key=lambda t: -t[1])  # stable
        kept: list[tuple[tuple[float, ...], float]] = []
        for b, s in mine:
            if all(plain_iou(b, kb) <= nms_iou for kb, _ in kept):
                kept.append((b, s))
        for b, s in kept:
            x1, x2 = min(max(b[0], 0.0), fw), min(max(b[2], 0.0), fw)
            y1, y2 = min(max(b[1], 0.0), fh), min(max(b[3], 0.0), fh)
            if x2 - x1 >= 1 and y2 - y1 >= 1:
                out.append((x1, y1, x2, y2, s, c))
    return out


def _rows(boxes) -> np.ndarray:
    """Rows (class, score, x1, y1, x2, y2) sorted, to compare two results as sets."""
    a = np.array([[c, s, *b] for *b, s, c in boxes], np.float64).reshape(-1, 6)
    return a[np.lexsort((a[:, 2], -a[:, 1], a[:, 0]))]


# ------------------------------------------------------------------ same boxes on real frames


@pytest.mark.parametrize(("clip", "numbers", "size"), [
    ("test_video.mp4", (1, 25), 640),
    pytest.param("highway_640.mp4", (1, 150), 640, marks=pytest.mark.slow),
    pytest.param("highway_640.mp4", (200,), 960, marks=pytest.mark.slow),
])
def test_detect_matches_the_slow_decode(model, data, clip, numbers, size):
    det = TeacherDetector(model, size=size, threads=2)
    frames = read_frames_at(data / "videos" / clip, numbers)
    assert sorted(frames) == list(numbers)
    total = 0
    for frame in frames.values():
        h, w = det.input_size(frame.shape)
        blob, r = det.preprocess(frame)
        ref_blob, ref_r = slow_letterbox(frame, h, w)
        assert r == ref_r
        np.testing.assert_array_equal(blob, ref_blob)
        raw, _ = det.raw(frame)
        fast = det.decode(raw, r, frame.shape)
        slow = slow_decode(raw, r, frame.shape[:2], (h, w))
        assert np.all(np.diff(fast.scores) <= 0)  # by score, highest first
        got = _rows([(*b, s, c) for b, s, c in zip(fast.boxes, fast.scores.astype(np.float64), fast.classes)])
        want = _rows(slow)
        assert got.shape == want.shape
        np.testing.assert_array_equal(got[:, 0], want[:, 0])
        np.testing.assert_allclose(got[:, 1], want[:, 1], rtol=1e-6)  # float32 scores
        np.testing.assert_allclose(got[:, 2:], want[:, 2:], atol=1e-6)
        total += len(fast)
        # detect() is preprocess + raw + decode
        again = det.detect(frame)
        np.testing.assert_array_equal(again.boxes, fast.boxes)
    assert total >= 3  # the frames have cars in them: the comparison compared something


def test_nms_matches_the_plain_loop():
    rng = np.random.default_rng(31)
    for _ in range(50):
        n = int(rng.integers(1, 40))
        xy = rng.uniform(0, 100, (n, 2))
        wh = rng.uniform(1, 40, (n, 2))
        boxes = np.c_[xy, xy + wh]
        scores = rng.choice([0.2, 0.5, 0.9], n) if rng.random() < 0.3 else rng.random(n)
        order = sorted(range(n), key=lambda i: -scores[i])
        kept: list[int] = []
        for i in order:
            if all(plain_iou(tuple(boxes[i]), tuple(boxes[k])) <= 0.45 for k in kept):
                kept.append(i)
        assert nms(boxes, scores, 0.45).tolist() == kept


@pytest.mark.parametrize(("shape", "size", "want"), [
    ((720, 1280), None, (384, 640)),   # 360 rounded up
    ((720, 1280), 960, (544, 960)),    # the README's 960x544
    ((360, 640), 640, (384, 640)),
    ((1920, 1080), 640, (1152, 640)),  # portrait
    ((480, 640), 650, (480, 640)),     # 650 rounds to 640
    ((720, 1280), 48, (64, 64)),       # 48 rounds (halves up) to 64 wide; 36 rows up to 64
    ((720, 1280), 32, (32, 32)),       # the smallest: 18 rows up to 32
])
def test_input_size(model, shape, size, want):
    det = TeacherDetector(model)
    if size is not None:  # the same model at another size, without loading it again
        det.config = TeacherConfig(size=size)
    assert det.input_size(shape) == want


def test_frame_without_vehicles_and_other_classes(model):
    det = TeacherDetector(model)
    grey = np.full((240, 320, 3), 114, np.uint8)
    out = det.detect(grey)
    assert len(out) == 0 and out.boxes.shape == (0, 4)
    assert len(out.detections()) == 0


# ------------------------------------------------------------------ models refused


def test_missing_and_non_onnx_files(tmp_path):
    with pytest.raises(ModelError, match="file not found"):
        TeacherDetector(tmp_path / "nope.onnx")
    with pytest.raises(ModelError, match="is a folder, expected an ONNX model file"):
        TeacherDetector(tmp_path)
    fifo = tmp_path / "pipe.onnx"  # issue 34's walk: adapt said "file not found" for a FIFO
    os.mkfifo(fifo)
    with pytest.raises(ModelError, match=r"is a named pipe \(FIFO\), not a regular file"):
        TeacherDetector(fifo)
    with pytest.raises(ModelError, match="is a device"):
        TeacherDetector("/dev/zero")
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"this is not a model\n" * 10)
    with pytest.raises(ModelError, match="not an ONNX model") as err:
        TeacherDetector(junk)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(("ios", "message"), [
    ([((1, 3, "h", "w"), FLOAT)], r"its output is tensor\(float\) \(1, 3, 'h', 'w'\), expected float32 \(1, N, 85\)"),
    ([((1, 3, 64, 64), FLOAT), ((1, "n", 85), FLOAT)], "it has 2 inputs"),
    ([((1, "n", 85), FLOAT)], r"its input is tensor\(float\) \(1, 'n', 85\)"),
    ([((1, 3, "h", "w"), INT64)], r"its input is tensor\(int64\)"),
    ([((1, 3, 100, 100), FLOAT)], r"its input is \(1, 3, 100, 100\): H and W must be multiples of 32"),
])
def test_models_of_another_layout_are_refused(tmp_path, ios, message):
    path = write_identity_model(tmp_path / "m.onnx", ios)
    with pytest.raises(ModelError, match="not a YOLOX-style detector: " + message) as err:
        TeacherDetector(path)
    assert "\n" not in str(err.value) and str(path) in str(err.value)


def test_settings_domain(model):
    for bad in ({"size": 0}, {"size": 5000}, {"min_score": 0.0}, {"min_score": float("nan")}, {"min_score": 1.5},
                {"threads": 0}):
        with pytest.raises(FastdetError):
            TeacherDetector(model, **bad)
    for bad_cfg in ({"nms_iou": 0}, {"classes": ()}, {"classes": (2, 2)}, {"classes": (80,)}, {"size": 31.5}):
        with pytest.raises(ValueError):
            TeacherConfig(**bad_cfg)
    assert TeacherConfig.from_dict(TeacherConfig(size=960).to_dict()) == TeacherConfig(size=960)


def test_threads_follow_numba_num_threads(model, monkeypatch):
    monkeypatch.setenv("NUMBA_NUM_THREADS", "1")
    assert TeacherDetector(model).threads == 1
    assert TeacherDetector(model, threads=2).threads == 2


def test_without_onnxruntime_one_line(model, monkeypatch):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # import onnxruntime -> ImportError
    with pytest.raises(FastdetError, match=r"pip install 'fastdet\[teacher\]'"):
        TeacherDetector(model)

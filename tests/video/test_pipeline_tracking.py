"""Tracking through VideoDetector and ``python -m fastdet video`` (ids, --offline, --count,
--line, --summary), with a FAKE detector (windows around each bright region) on synthetic
videos of bright rectangles, so these tests do not depend on a trained model."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet.cli import video
from fastdet.cli.main import build_parser
from fastdet.config import HeatConfig, PipelineConfig, TrackerConfig
from fastdet.detections import Detections
from fastdet.errors import FastdetError
from fastdet.eval.metrics import evaluate
from fastdet.io.motfiles import read_predictions
from fastdet.video import VideoDetector, iter_video_detections
from tests.fakes import BlobsDetector
from tests.reference import box_iou as iou

W, H = 480, 240
HEAT = HeatConfig(n_frames=1, threshold=8.0, min_width=20, min_height=20)
# the synthetic blobs are not vehicles: the learned box refinement (trained on cars) is off
HEAT_ARGS = ("--heat-frames", "1", "--heat-threshold", "8", "--no-refine")


def cars_at(i: int, merge: bool = False) -> list[tuple[int, int, int, int]]:
    """The bright rectangles of frame ``i``: car A moving right from x = 10; car B (from frame
    8) moving left from x = 300; with ``merge``, car C riding beside A, 10 px to its right
    (touching it, 0 px apart, in frames 10..14)."""
    xa = 10 + 8 * i
    out = [(xa, 100, xa + 60, 140)]
    if merge:
        gap = 0 if 10 <= i < 15 else 10
        out.append((xa + 60 + gap, 100, xa + 120 + gap, 140))
    elif i >= 8:
        xb = 300 - 10 * (i - 8)
        out.append((xb, 160, xb + 60, 200))
    return out


def frame_of(i: int, merge: bool = False) -> np.ndarray:
    f = np.full((H, W, 3), 40, np.uint8)
    for x1, y1, x2, y2 in cars_at(i, merge):
        f[y1:y2, x1:x2] = 250
    return f


def write_video(path: Path, n: int, merge: bool = False) -> Path:
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25, (W, H))
    assert w.isOpened()
    for i in range(n):
        w.write(frame_of(i, merge))
    w.release()
    return path


def parse(*argv):
    return build_parser("video").parse_args(["video", *map(str, argv)])


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    return write_video(tmp_path_factory.mktemp("tracking") / "cars.avi", 24)


def ground_truth(n: int) -> Detections:
    rows = [(i + 1, k + 1, b) for i in range(n) for k, b in enumerate(cars_at(i))]
    return Detections(np.array([r[2] for r in rows], float), frames=np.array([r[0] for r in rows]),
                      ids=np.array([r[1] for r in rows]), consider=np.ones(len(rows), bool))


# ------------------------------------------------------------------------- VideoDetector


def test_every_box_has_an_id_and_ids_start_at_1():
    vd = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None))
    outs = [vd.update(frame_of(i)) for i in range(24)]
    for i, out in enumerate(outs):
        assert out.ids is not None and len(out) == len(cars_at(i)), i
        for b, tid in zip(out.boxes, out.ids):
            assert iou(b, cars_at(i)[tid - 1]) > 0.7, (i, tid)  # id 1 = car A, id 2 = car B
    assert set(vd.timings) >= {"weak", "track"}
    assert vd.debug.tracks and vd.debug.tracks[0][:2] == (1, "tracked")
    # reset: ids start again at 1; a new VideoDetector gives the same ids
    vd.reset()
    again = [vd.update(frame_of(i)) for i in range(24)]
    fresh = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None))
    third = [fresh.update(frame_of(i)) for i in range(24)]
    for a, b, c in zip(outs, again, third):
        assert a.ids.tolist() == b.ids.tolist() == c.ids.tolist()
        np.testing.assert_array_equal(a.boxes, c.boxes)


def test_update_is_causal():
    # the boxes of the first k frames do not depend on the frames after them
    full = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None))
    a = [full.update(frame_of(i)) for i in range(24)]
    part = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None))
    b = [part.update(frame_of(i)) for i in range(12)]
    for x, y in zip(a[:12], b):
        np.testing.assert_array_equal(x.boxes, y.boxes)
        assert x.ids.tolist() == y.ids.tolist()


def test_no_tracker_gives_the_heat_map_boxes_without_ids():
    vd = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None, tracker=None))
    tracked = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None))
    for i in range(24):
        plain, out = vd.update(frame_of(i)), tracked.update(frame_of(i))
        assert plain.ids is None
        assert sorted(map(tuple, plain.boxes.tolist())) == sorted(map(tuple, out.boxes.tolist()))
    with pytest.raises(TypeError):
        PipelineConfig(heat=HEAT, refine=None, tracker=HEAT)


def test_two_touching_cars_keep_two_boxes_and_two_ids():
    # cars A and C side by side: for frames 10..14 they touch, their windows form one bright
    # region and the heat map one blob; the tracker splits it by the two tracks' predictions
    vd = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None))
    plain = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None, tracker=None))
    for i in range(20):
        out = vd.update(frame_of(i, merge=True))
        blobs = plain.update(frame_of(i, merge=True))
        if 10 <= i < 15:
            assert len(blobs) == 1  # what the heat map gives
        assert out.ids.tolist() == [1, 2], i
        for b, truth in zip(out.boxes, cars_at(i, merge=True)):
            assert iou(b, truth) > 0.6, (i, b, truth)


def test_iter_video_detections_offline_yields_every_frame(clip):
    live = list(iter_video_detections(clip, PipelineConfig(heat=HEAT, refine=None), detector=BlobsDetector(),
                                      progress=False))
    off = list(iter_video_detections(clip, PipelineConfig(heat=HEAT, refine=None), detector=BlobsDetector(),
                                     progress=False, offline=True))
    assert [f for f, _ in off] == [f for f, _ in live] == list(range(1, 25))
    for (_, a), (_, b) in zip(live, off):  # nothing to fill on a clean clip
        assert a.ids.tolist() == b.ids.tolist()
    with pytest.raises(ValueError):
        list(iter_video_detections(clip, PipelineConfig(tracker=None), detector=BlobsDetector(), progress=False,
                                   offline=True))


# ------------------------------------------------------------------------- CLI


def test_cli_writes_ids_counts_and_summary(clip, tmp_path, capsys):
    boxes, js, summ = tmp_path / "b.txt", tmp_path / "b.jsonl", tmp_path / "s.json"
    # a vertical line at x = 200: car A crosses it left to right in the picture (its
    # right side as seen walking down the line), car B right to left
    rc = video.run(parse(clip, "--boxes", boxes, "--json", js, "--summary", summ, "--line", "200,0,200,240",
                         "--no-progress", *HEAT_ARGS), detector=BlobsDetector())
    assert rc == 0
    preds = read_predictions(boxes)
    assert (preds.ids >= 1).all() and sorted(set(preds.ids.tolist())) == [1, 2]
    assert read_predictions(js).ids.tolist() == preds.ids.tolist()
    result = evaluate(ground_truth(24), preds)
    assert result.has_tracking and result.id_switches == 0 and result.idf1 > 0.95
    info = json.loads(summ.read_text())
    assert info["frames"] == 24 and info["vehicles"] == 2
    assert info["line"]["right_to_left"] == 1 and info["line"]["left_to_right"] == 1
    assert info["outputs"] == [str(boxes), str(js)]
    printed = capsys.readouterr().out
    assert "2 vehicles" in printed and "1 left to right, 1 right to left" in printed


def test_cli_offline_and_video(clip, tmp_path, capsys):
    out, boxes = tmp_path / "o.mp4", tmp_path / "b.txt"
    rc = video.run(parse(clip, "-o", out, "--boxes", boxes, "--offline", "--count", "--debug", "--no-progress",
                         *HEAT_ARGS), detector=BlobsDetector())
    assert rc == 0
    cap = cv2.VideoCapture(str(out))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    assert n == 24
    assert sorted(set(read_predictions(boxes).ids.tolist())) == [1, 2]
    assert "2 vehicles" in capsys.readouterr().out


def test_cli_refuses_counting_without_tracker_and_offline_with_no_track(clip, tmp_path):
    with pytest.raises(FastdetError, match="need the tracker"):
        video.run(parse(clip, "--count", "--no-track", "--no-progress"), detector=BlobsDetector())
    with pytest.raises(SystemExit):
        parse(clip, "--boxes", tmp_path / "b.txt", "--offline", "--no-track")
    with pytest.raises(SystemExit):
        parse(clip, "--line", "1,2,3")


def test_tracker_config_reaches_the_video_detector():
    vd = VideoDetector(BlobsDetector(), PipelineConfig(heat=HEAT, refine=None, tracker=TrackerConfig(min_hits=3)))
    outs = [vd.update(frame_of(i)) for i in range(4)]
    assert [o.ids.tolist() for o in outs] == [[], [], [1], [1]]

"""Box files written from the one box table: a frame's Detections, a whole clip's table, and
what a box file cannot hold (ground truth without scores, rows of another frame)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fastdet.detections import Detections
from fastdet.io.motfiles import JsonLinesWriter, MotWriter, parse_gt, read_predictions


def _clip() -> Detections:
    return Detections.from_frames([
        (2, Detections(np.array([[5, 5, 15, 25]], np.int32), np.array([1.5], np.float32), ids=[3])),
        (1, Detections(np.array([[10, 20, 60, 70], [100, 100, 140, 130]], np.int32),
                       np.array([0.9, 0.25], np.float32))),
        (3, Detections.empty()),
    ], source="clip.mp4")


@pytest.mark.parametrize("writer, name", [(MotWriter, "boxes.txt"), (JsonLinesWriter, "boxes.jsonl")])
def test_a_clip_table_is_written_by_frame_and_read_back(tmp_path, writer, name):
    table, path = _clip(), tmp_path / name
    with writer(path) as w:
        w.write_table(table)
    got = read_predictions(path)
    assert got.frames.tolist() == [1, 1, 2] and got.ids.tolist() == [-1, -1, 3]  # by ascending frame
    np.testing.assert_array_equal(got.boxes, [[10, 20, 60, 70], [100, 100, 140, 130], [5, 5, 15, 25]])
    assert got.scores.tolist() == [np.float32(0.9), np.float32(0.25), 1.5]
    assert got.source == str(path) and got.boxes.dtype == np.float64  # a file's continuous coordinates
    # what was read writes the same file again, byte for byte
    again = tmp_path / ("again" + path.suffix)
    with writer(again) as w:
        w.write_table(got)
    assert again.read_bytes() == path.read_bytes()


def test_frame_by_frame_is_the_same_file_as_the_table(tmp_path):
    table = _clip()
    with MotWriter(tmp_path / "a.txt") as a, MotWriter(tmp_path / "b.txt") as b:
        a.write_table(table)
        for f, rows in table.by_frame():
            b.write_detections(f, Detections(rows.boxes, rows.scores, ids=rows.ids))
    assert (tmp_path / "a.txt").read_text() == (tmp_path / "b.txt").read_text()
    lines = [json.loads(s) for s in _jsonl(tmp_path, table).splitlines()]
    assert [o["frame"] for o in lines] == [1, 2]


def _jsonl(tmp_path, table: Detections) -> str:
    with JsonLinesWriter(tmp_path / "t.jsonl") as w:
        w.write_table(table)
    return (tmp_path / "t.jsonl").read_text()


def test_what_a_box_file_cannot_hold(tmp_path):
    gt = parse_gt("1,1,10,10,20,20,1,1,1\n", "gt.txt")
    with MotWriter(tmp_path / "x.txt") as w:
        with pytest.raises(ValueError, match="no scores"):
            w.write_table(gt)
        with pytest.raises(ValueError, match="frame 2, but the rows say frames \\[1, 2\\]"):
            w.write_detections(2, _clip()[:2])
        with pytest.raises(ValueError, match="frame must be >= 1"):
            w.write_detections(0, Detections.empty())
        with pytest.raises(ValueError, match="2 boxes but 1 scores"):
            w.write(1, [[0, 0, 1, 1], [0, 0, 2, 2]], [0.5])
        with pytest.raises(ValueError, match="no frames column"):
            w.write_table(Detections.empty())

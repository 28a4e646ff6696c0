"""Box files: numbers out of their domain are refused in one line naming the file and line."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.errors import DataError
from fastdet.io.motfiles import MAX_FRAME, parse_gt, parse_jsonl_predictions, parse_predictions, read_predictions


@pytest.mark.parametrize("line", ["1e30,1,1,1,5,5,1,1,1", "9223372036854775807,1,1,1,5,5,1,1,1",
                                  f"{MAX_FRAME + 1},1,1,1,5,5"])
def test_gt_frame_out_of_range(line):
    with pytest.raises(DataError, match="line 1: frame .* is out of range"):
        parse_gt(line, "g.txt")


@pytest.mark.parametrize("tid", ["1e30", "-1e30", "9223372036854775807"])
def test_gt_and_prediction_id_out_of_range(tid):
    with pytest.raises(DataError, match="g.txt: line 2: id .* is out of range"):
        parse_gt(f"1,1,1,1,5,5\n2,{tid},1,1,5,5", "g.txt")
    with pytest.raises(DataError, match="p.txt: line 1: id .* is out of range"):
        parse_predictions(f"1,{tid},1,1,5,5,0.5", "p.txt")


def test_largest_frame_and_id_still_read():
    gt = parse_gt(f"{MAX_FRAME},{MAX_FRAME},1,1,5,5", "g.txt")
    assert int(gt.frames[0]) == MAX_FRAME and int(gt.ids[0]) == MAX_FRAME


@pytest.mark.parametrize("obj, msg", [
    ('{"frame": 100000000000000000000000, "boxes": [], "scores": []}', "frame .* is out of range"),
    ('{"frame": 1, "boxes": [[0,0,5,5]], "scores": [1], "ids": [100000000000000000000000]}', "out of range"),
    ('{"frame": 1, "boxes": [[0,0,5,5]], "scores": [1], "ids": [777.5]}', "whole number, got 777.5"),
    ('{"frame": 1, "boxes": [[0,0,5,5]], "scores": [1], "ids": [true]}', "whole number"),
    ('{"frame": 1, "boxes": [[0,0,5,5]], "scores": [1], "ids": ["7"]}', "whole number"),
    ('{"frame": 1, "boxes": [[0,0,5,5]], "scores": [1], "ids": 7}', "must be a list"),
])
def test_jsonl_numbers_out_of_domain(obj, msg):
    with pytest.raises(DataError, match=f"p.jsonl: line 1: .*{msg}"):
        parse_jsonl_predictions(obj, "p.jsonl")


def test_jsonl_whole_float_id_is_read_as_int():
    p = parse_jsonl_predictions('{"frame": 2, "boxes": [[0,0,5,5]], "scores": [1], "ids": [777.0]}', "p.jsonl")
    assert p.ids.tolist() == [777] and p.frames.tolist() == [2]


def test_files_read_into_the_one_box_table():
    """Ground truth: frames, ids, boxes (the file's continuous coordinates) and consider, no
    scores; predictions: frames, ids, boxes and scores (float64, as written), no consider."""
    from fastdet.detections import Detections

    gt = parse_gt("1,1,10.5,10,20,20,1,1,1\n2,7,0,0,5,5,0\n", "g.txt")
    assert isinstance(gt, Detections) and gt.scores is None and gt.source == "g.txt"
    assert gt.boxes.dtype == np.float64 and gt.boxes.tolist() == [[10.5, 10, 30.5, 30], [0, 0, 5, 5]]
    assert gt.frames.tolist() == [1, 2] and gt.ids.tolist() == [1, 7] and gt.consider.tolist() == [True, False]
    assert gt.num_frames == 2 and gt.num_considered == 1
    p = parse_predictions("3,-1,1,2,3,4,0.123456789,-1,-1,-1\n", "p.txt")
    assert p.consider is None and p.scores.dtype == np.float64 and p.scores.tolist() == [0.123456789]
    assert p.frames.tolist() == [3] and p.ids.tolist() == [-1] and not p.has_ids
    none = parse_predictions("", "p.txt")
    assert len(none) == 0 and none.frames is not None and none.scores is not None


def test_jsonl_nested_too_deeply_is_one_line(tmp_path):
    """issue 34, item 19: 200,000 nested ``[`` gave a RecursionError traceback."""
    p = tmp_path / "p.jsonl"
    p.write_text('{"frame": 1, "boxes": [], "scores": []}\n' + "[" * 200_000 + "\n")
    with pytest.raises(DataError, match="line 2: not a box line .JSON: nested too deeply"):
        read_predictions(p)
    p.write_text('{"frame": 1, "boxes": [], "scores": []}\n{"frame": ' + "9" * 5000 + ', "boxes": []}\n')
    with pytest.raises(DataError, match="line 2: not a box line .JSON: a number too long"):  # a ValueError traceback
        read_predictions(p)


@pytest.mark.parametrize("line", ["1,1,1e200,10,40,30,0.9", "1,1,1e308,10,1e308,30,0.9", "1,1,10,10,40,-1e300,0.9",
                                  "1,1,-1e200,10,40,30,0.9"])
def test_huge_coordinates_are_one_line(line):
    """Issue 34 (17): boxes of 1e200 or 1e308 + 1e308 gave overflow warnings and metrics over
    infinite boxes."""
    with pytest.raises(DataError, match="p.txt: line 1: .*(is out of range|negative box size)"):
        parse_predictions(line + "\n", "p.txt")
    with pytest.raises(DataError, match="g.txt: line 1: .*(is out of range|negative box size)"):
        parse_gt(line.rsplit(",", 1)[0] + "\n", "g.txt")


def test_huge_json_coordinates_are_one_line():
    with pytest.raises(DataError, match="line 1: a box coordinate is out of range"):
        parse_jsonl_predictions('{"frame": 1, "boxes": [[0, 0, 1e200, 5]], "scores": [1]}\n', "p.jsonl")

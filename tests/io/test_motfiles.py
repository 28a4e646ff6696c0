"""Box files: numbers out of their domain are refused in one line naming the file and line."""
from __future__ import annotations

import pytest

from fastdet.errors import DataError
from fastdet.io.motfiles import MAX_FRAME, parse_gt, parse_jsonl_predictions, parse_predictions


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

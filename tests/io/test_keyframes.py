"""fastdet.io.keyframes: reading the keyframe list of a sparsely annotated clip."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.errors import DataError
from fastdet.io.keyframes import (
    keyframes_for,
    keyframes_path,
    parse_keyframes,
    read_keyframes,
)


def test_parse_sorts_and_skips_blank_lines():
    np.testing.assert_array_equal(parse_keyframes("11\n\n 1 \n21\n"), [1, 11, 21])
    assert parse_keyframes("5").dtype == np.int64


@pytest.mark.parametrize("text, words", [
    ("1\nx\n", "line 2: expected a frame number"),
    ("1\n2.5\n", "line 2: expected a frame number"),
    ("0\n", "line 1: frame must be >= 1"),
    ("3\n4\n3\n", "line 3: frame 3 is listed twice (first on line 1)"),
    ("\n \n", "no frame numbers"),
    ("1\n" + "1" + "0" * 29 + "\n", "line 2: frame 1" + "0" * 29 + " is out of range (at most 2147483647)"),
    ("2147483648\n", "line 1: frame 2147483648 is out of range"),
])
def test_parse_refuses_bad_lists(text, words):
    with pytest.raises(DataError, match="kf.frames: " + r".*" + words.replace("(", r"\(").replace(")", r"\)")):
        parse_keyframes(text, "kf.frames")


def test_path_beside_the_ground_truth(tmp_path):
    gt = tmp_path / "clip.gt.txt"
    assert keyframes_path(gt) == tmp_path / "clip.frames"
    assert keyframes_path(tmp_path / "other.txt") == tmp_path / "other.frames"
    assert keyframes_for(gt) is None  # no list: a densely annotated clip
    (tmp_path / "clip.frames").write_text("6\n1\n")
    np.testing.assert_array_equal(keyframes_for(gt), [1, 6])


def test_read_errors(tmp_path):
    with pytest.raises(DataError, match="missing.frames: file not found"):
        read_keyframes(tmp_path / "missing.frames")
    with pytest.raises(DataError, match="is a directory"):
        read_keyframes(tmp_path)
    bad = tmp_path / "bin.frames"
    bad.write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(DataError, match="not a text file"):
        read_keyframes(bad)


def test_the_shared_keyframe_lists(data):
    """Every keyframe list of the data folder reads, and its clip's ground truth lies on
    listed frames only."""
    from fastdet.io.motfiles import read_gt

    lists = sorted((data / "annotations").glob("*.frames"))
    assert lists
    for f in lists:
        kf = read_keyframes(f)
        gt = read_gt(f.with_name(f.name[: -len(".frames")] + ".gt.txt"))
        assert np.isin(gt.frames, kf).all(), f

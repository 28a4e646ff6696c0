"""Crops cut from annotated frames: window placement, cutting past the edge, positives by
aspect, negatives that never touch an annotated box."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.boxes import intersection
from fastdet.errors import DataError
from fastdet.io.reader import read_frames
from fastdet.train.keyframes import (
    AnnotatedFrame,
    annotated_frame_numbers,
    aspect_of,
    background_crops,
    cut,
    false_window_crops,
    positive_crops,
    read_annotated_frames,
    window_around,
)
from tests.media import write_video


def _frame(targets, ignores=(), shape=(120, 200), seed=0):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
    return AnnotatedFrame("clip", 1, img, np.array(targets, float).reshape(-1, 4),
                          np.array(ignores, float).reshape(-1, 4))


@settings(max_examples=60, deadline=None)
@given(st.floats(1, 500), st.floats(1, 500), st.sampled_from([(64, 32), (64, 64), (64, 48), (64, 24)]),
       st.floats(0, 0.3))
def test_window_around_has_the_window_aspect_and_holds_the_box(w, h, win, margin):
    box = np.array([10.0, 20.0, 10 + w, 20 + h])
    out = window_around(box, *win, margin)
    ow, oh = out[2] - out[0], out[3] - out[1]
    assert ow / oh == pytest.approx(win[0] / win[1], rel=1e-9)
    assert out[0] <= box[0] + 1e-9 and out[1] <= box[1] + 1e-9 and out[2] >= box[2] - 1e-9 and out[3] >= box[3] - 1e-9
    # one side is the box's, grown by the margin only
    assert min(ow / (w * (1 + 2 * margin)), oh / (h * (1 + 2 * margin))) == pytest.approx(1.0, rel=1e-9)
    assert (out[0] + out[2]) / 2 == pytest.approx(10 + w / 2) and (out[1] + out[3]) / 2 == pytest.approx(20 + h / 2)


def test_cut_inside_is_the_resized_region_and_past_the_edge_repeats_it():
    img = np.zeros((40, 60, 3), np.uint8)
    img[:, :30] = 200
    assert (cut(img, np.array([0, 0, 30, 40]), 15, 20) == 200).all()
    # a box hanging 10 px over the left edge: the repeated edge column is 200 as well
    assert (cut(img, np.array([-10, 0, 20, 40]), 15, 20) == 200).all()
    # past the right edge the repeated column is 0
    right = cut(img, np.array([50, 0, 70, 40]), 10, 20)
    assert (right == 0).all()
    with pytest.raises(ValueError):
        cut(img, np.array([5, 5, 6, 6]), 8, 8)


def test_positive_crops_by_aspect_width_and_jitter():
    wide = [20, 40, 100, 80]   # 80x40: aspect 2
    square = [120, 30, 170, 80]  # 50x50: aspect 1
    f = _frame([wide, square])
    assert aspect_of(f.targets).tolist() == [2.0, 1.0]
    one = positive_crops([f], 64, 32, aspect_range=(1.6, np.inf))
    assert one.shape == (1, 32, 64, 3)
    np.testing.assert_array_equal(one[0], cut(f.image, window_around(np.array(wide, float), 64, 32, 0.0625), 64, 32))
    assert positive_crops([f], 64, 64, aspect_range=(0.5, 1.6)).shape == (1, 64, 64, 3)
    assert positive_crops([f], 64, 32, aspect_range=(1.6, np.inf), jitter=3).shape == (4, 32, 64, 3)
    # a box narrower than min_width x the frame width is left out
    assert len(positive_crops([f], 64, 32, aspect_range=(1.6, np.inf), min_width=0.5)) == 0
    # seeded: the same copies again
    a = positive_crops([f], 64, 32, jitter=2, seed=3)
    np.testing.assert_array_equal(a, positive_crops([f], 64, 32, jitter=2, seed=3))


def test_background_and_false_windows_touch_no_annotated_box():
    f = _frame([[20, 40, 100, 80]], ignores=[[150, 10, 190, 40]])
    for seed in range(3):
        crops = background_crops([f], 64, 32, per_frame=10, widths=(0.1, 0.3), seed=seed)
        assert crops.shape[1:] == (32, 64, 3) and 0 < len(crops) <= 10
    # false windows: one touching the target, one touching the ignore region, one clear of both
    wins = np.array([[90, 70, 130, 90], [140, 30, 160, 50], [110, 90, 150, 110]], float)
    hard = false_window_crops([f], [wins], 64, 32)
    assert hard.shape == (1, 32, 64, 3)
    np.testing.assert_array_equal(hard[0], cut(f.image, wins[2], 64, 32))
    assert not (intersection(wins[2:], f.boxes) > 0).any()
    assert len(false_window_crops([f], [wins], 64, 32, limit=0)) == 0


def test_real_keyframe_clip_frames_and_boxes(data):
    nums = annotated_frame_numbers(data, "boston_street")
    assert nums == [int(v) for v in (data / "annotations" / "boston_street.frames").read_text().split()]
    assert annotated_frame_numbers(data, "test_video", every=5) == list(range(1, 39, 5))
    frames = read_annotated_frames(data, "boston_street")
    assert [f.frame for f in frames] == nums
    rows = np.loadtxt(data / "annotations" / "boston_street.gt.txt", delimiter=",")
    f = frames[1]
    r = rows[(rows[:, 0] == f.frame) & (rows[:, 6] == 1)]
    np.testing.assert_allclose(f.targets, np.c_[r[:, 2], r[:, 3], r[:, 2] + r[:, 4], r[:, 3] + r[:, 5]])
    assert f.image.shape == (450, 800, 3) and f.image.dtype == np.uint8
    assert len(f.ignores) == int(((rows[:, 0] == f.frame) & (rows[:, 6] == 0)).sum())


def _clip(root: Path, frames: int, keyframes: list[int]) -> Path:
    """A data folder with one keyframe clip ``c``: a ``frames``-frame video, one target box on
    each of ``keyframes`` and an ignore region on the first."""
    (root / "videos").mkdir(parents=True)
    (root / "annotations").mkdir()
    write_video(root / "videos" / "c.mp4", frames)
    lines = [f"{k},1,{10 + k},20,40,30,1,-1,-1" for k in keyframes] + [f"{keyframes[0]},2,200,100,50,40,0,-1,-1"]
    (root / "annotations" / "c.gt.txt").write_text("\n".join(lines) + "\n")
    (root / "annotations" / "c.frames").write_text(" ".join(map(str, keyframes)) + "\n")
    return root


def test_annotated_frames_are_the_videos_frames_with_their_boxes(tmp_path):
    data = _clip(tmp_path, 12, [3, 7, 12])
    every = read_frames(data / "videos" / "c.mp4")
    got = read_annotated_frames(data, "c")
    assert [f.frame for f in got] == [3, 7, 12]
    for f in got:
        np.testing.assert_array_equal(f.image, every[f.frame - 1])
        np.testing.assert_array_equal(f.targets, [[10 + f.frame, 20, 50 + f.frame, 50]])
    assert got[0].ignores.tolist() == [[200, 100, 250, 140]] and got[1].ignores.shape == (0, 4)


def test_a_video_that_ends_before_its_last_keyframe_is_one_clear_error(tmp_path):
    data = _clip(tmp_path, 12, [3, 7, 15])
    with pytest.raises(DataError) as err:
        read_annotated_frames(data, "c")
    assert str(err.value) == f"{data / 'videos' / 'c.mp4'}: ends after 12 frames, before annotated frame 15"
    (data / "videos" / "c.mp4").write_bytes(b"not a video")
    with pytest.raises(DataError, match="c.mp4: not a video"):
        read_annotated_frames(data, "c")
    (data / "videos" / "c.mp4").unlink()
    with pytest.raises(DataError, match="c.mp4: file not found"):
        read_annotated_frames(data, "c")

"""fastdet.labels.load: pixels of many pictures, a video decoded once for its frames."""
from __future__ import annotations

import numpy as np

from fastdet.io.reader import read_frames_at
from fastdet.labels.load import load_picture, load_pictures
from fastdet.labels.picture import AnnotatedPicture

from .synth import one_error, picture


def test_frames_of_a_video_and_stills_in_order(data, tmp_path):
    video = data / "videos" / "test_video.mp4"
    still = picture(tmp_path / "a.jpg", 32, 16)
    pics = [AnnotatedPicture("v", "c", f"test_video:{f}", video, 1280, 720, frame=f) for f in (1, 6)]
    pics.insert(1, AnnotatedPicture("s", "c", "a.jpg", still, 32, 16))
    pics.append(AnnotatedPicture("v", "c", "test_video:11", video, 1280, 720, frame=11))
    got = list(load_pictures(pics))
    assert [p for p, _ in got] == pics
    assert got[1][1].shape == (16, 32, 3)
    want = read_frames_at(video, [6, 11], notify=lambda _: None)
    np.testing.assert_array_equal(got[2][1], want[6])
    np.testing.assert_array_equal(got[3][1], want[11])
    np.testing.assert_array_equal(load_picture(pics[3]), want[11])


def test_a_frame_past_the_end(data):
    video = data / "videos" / "test_video.mp4"
    pic = AnnotatedPicture("v", "c", "test_video:500", video, 1280, 720, frame=500)
    one_error(lambda: list(load_pictures([pic])), video, "ends before frame 500")

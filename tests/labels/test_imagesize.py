"""fastdet.labels.imagesize: picture sizes from file headers, video sizes from containers."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.labels.imagesize import header_size, image_size, video_size

from .synth import one_error, picture, write


@settings(max_examples=25, deadline=None)
@given(w=st.integers(1, 700), h=st.integers(1, 700), kind=st.sampled_from([".jpg", ".png", "progressive"]))
def test_header_size_is_the_decoded_size(tmp_path_factory, w, h, kind):
    d = tmp_path_factory.mktemp("img")
    img = np.random.default_rng(w * 1000 + h).integers(0, 255, (h, w, 3), dtype=np.uint8)
    if kind == "progressive":  # SOF2 instead of SOF0
        ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
        path = d / "p.jpg"
    else:
        ok, data = cv2.imencode(kind, img)
        path = d / f"p{kind}"
    assert ok
    path.write_bytes(data.tobytes())
    decoded = cv2.imread(str(path))
    assert header_size(path) == (decoded.shape[1], decoded.shape[0]) == (w, h)
    assert image_size(path) == (w, h)


def test_jpeg_with_exif_and_comment_segments(tmp_path):
    """APPn / COM segments before the frame header are skipped by their lengths."""
    ok, data = cv2.imencode(".jpg", np.zeros((37, 91, 3), np.uint8))
    raw = data.tobytes()
    extra = b"\xff\xe1" + (2 + 300).to_bytes(2, "big") + b"\xc0" * 300  # an APP1 full of fake SOF bytes
    extra += b"\xff\xfe" + (2 + 5).to_bytes(2, "big") + b"hello"
    p = tmp_path / "x.jpg"
    p.write_bytes(raw[:2] + extra + raw[2:])
    assert header_size(p) == (91, 37)


def test_other_formats_fall_back_to_decoding(tmp_path):
    p = picture(tmp_path / "a.bmp", 33, 21)
    assert header_size(p) is None
    assert image_size(p) == (33, 21)


def test_image_errors(tmp_path):
    one_error(lambda: image_size(tmp_path / "missing.jpg"), tmp_path / "missing.jpg", "not found")
    one_error(lambda: image_size(tmp_path), tmp_path, "folder")
    junk = write(tmp_path / "junk.jpg", "not a picture")
    one_error(lambda: image_size(junk), junk, "not an image")
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(b"\xff\xd8\xff\xe0\x00")  # a JPEG cut inside its first segment
    assert header_size(cut) is None
    one_error(lambda: image_size(cut), cut, "not an image")


def test_real_pictures_sizes(data):
    paths = sorted((data / "frames").rglob("*.jpg"))[::25]
    assert len(paths) > 20
    for p in paths:
        img = cv2.imread(str(p))
        assert image_size(p) == (img.shape[1], img.shape[0]), p


@pytest.mark.parametrize("clip, size", [("test_video.mp4", (1280, 720)), ("ebuarip_640.avi", (640, 480)),
                                        ("j219_road.mp4", (352, 640)), ("haroon_road.mp4", (1080, 1920))])
def test_real_video_sizes(data, clip, size):
    """Including a portrait clip whose container holds a rotation (j219_road: decoded 352 wide)."""
    assert video_size(data / "videos" / clip) == size


def test_video_errors(tmp_path):
    one_error(lambda: video_size(tmp_path / "none.mp4"), tmp_path / "none.mp4", "not found")
    junk = write(tmp_path / "junk.mp4", "no video here")
    one_error(lambda: video_size(junk), junk, "not a video")

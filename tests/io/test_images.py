"""fastdet/io/images.py: images read strictly (a JPEG cut short at any byte is refused, though
OpenCV decodes it) and written atomically. Through the commands (one line, exit 2, full disks):
tests/cli/test_robust_inputs.py, tests/cli/test_robust_writes.py."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.errors import DataError
from fastdet.io.images import check_image, jpeg_complete, read_image, write_image


def _picture() -> np.ndarray:
    img = np.zeros((48, 64, 3), np.uint8)
    img[:, :32] = (20, 200, 90)
    img[10:30, 40:60] = 255
    return img


def test_a_jpeg_is_complete_only_with_its_end_marker_after_the_last_scan():
    ok, buf = cv2.imencode(".jpg", _picture())
    data = buf.tobytes()
    assert ok and jpeg_complete(data)
    sos = data.rfind(b"\xff\xda")
    # cut anywhere from the start of the last scan on (before its FF D9): incomplete
    for n in range(sos, len(data) - 1, max(1, (len(data) - sos) // 40)):
        assert not jpeg_complete(data[:n]), n
    assert not jpeg_complete(data[:len(data) - 1])
    assert not jpeg_complete(data[:sos])  # no scan at all
    ok, png = cv2.imencode(".png", _picture())
    assert jpeg_complete(png.tobytes()) and jpeg_complete(b"")  # not a JPEG: nothing to say


def test_read_image_refuses_what_is_not_a_whole_image(tmp_path):
    good = tmp_path / "a.jpg"
    assert cv2.imwrite(str(good), _picture())
    img = read_image(good)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    data = good.read_bytes()
    (tmp_path / "cut.jpg").write_bytes(data[: len(data) * 3 // 4])
    assert cv2.imread(str(tmp_path / "cut.jpg")) is not None  # OpenCV decodes it...
    with pytest.raises(DataError, match="cut short"):  # ... we do not
        read_image(tmp_path / "cut.jpg")
    with pytest.raises(DataError, match="cut short"):
        check_image(tmp_path / "cut.jpg")
    (tmp_path / "text.png").write_text("not an image")
    for path, msg in ((tmp_path / "none.jpg", "file not found"), (tmp_path, "is a folder"),
                      (tmp_path / "text.png", "not an image")):
        with pytest.raises(DataError, match=msg):
            read_image(path)
    with pytest.raises(DataError, match="file not found"):
        check_image(tmp_path / "none.jpg")


@pytest.mark.parametrize("ext", [".png", ".jpg"])
def test_write_image_round_trip_and_no_temporary_name_left(tmp_path, ext):
    out = write_image(tmp_path / f"o{ext}", _picture())
    assert out == tmp_path / f"o{ext}" and [p.name for p in tmp_path.iterdir()] == [f"o{ext}"]
    back = read_image(out)
    if ext == ".png":
        np.testing.assert_array_equal(back, _picture())
    else:
        assert np.abs(back.astype(int) - _picture()).mean() < 8


def test_write_image_refuses_an_extension_it_cannot_write(tmp_path):
    with pytest.raises(DataError, match="extension '.txt'"):
        write_image(tmp_path / "o.txt", _picture())
    with pytest.raises(DataError, match=r"\(none\)"):
        write_image(tmp_path / "o", _picture())
    assert list(tmp_path.iterdir()) == []

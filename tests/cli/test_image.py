"""``python -m fastdet image`` with a fake detector (windows around bright regions), and its
bad-input errors; plus the drawing helpers it uses."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet import cli
from fastdet.cli import image as imagecmd
from fastdet.cli.main import build_parser
from fastdet.config import HeatConfig
from fastdet.detections import WIDE_PART, Detections
from fastdet.errors import DataError
from fastdet.io import draw
from fastdet.video import detect_image
from tests.fakes import BlobsDetector

FAKE = BlobsDetector(score=2.0, scales=True)  # windows around each bright rectangle


@pytest.fixture
def image(tmp_path) -> Path:
    img = np.full((240, 320, 3), 30, np.uint8)
    img[100:160, 40:120] = 255   # a "vehicle"
    img[20:90, 200:215] = 255    # a pole: too narrow and too tall, dropped by the shape filter
    path = tmp_path / "in.png"
    cv2.imwrite(str(path), img)
    return path


def parse(*argv):
    return build_parser("image").parse_args(["image", *map(str, argv)])


def test_image_boxes_windows_heat(image, tmp_path, capsys):
    out = tmp_path / "out.jpg"
    assert imagecmd.run(parse(image, "-o", out, "--windows", "--heat"), detector=FAKE) == 0
    assert "1 vehicle(s) from 10 positive window(s)" in capsys.readouterr().out
    res = cv2.imread(str(out))
    heat = cv2.imread(str(tmp_path / "out.heat.jpg"))
    assert res.shape == heat.shape == (240, 320, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png", "out.heat.jpg", "out.jpg"]  # no partials
    # the final box is drawn in green around the vehicle
    green = (res[:, :, 1] > 200) & (res[:, :, 0] < 80) & (res[:, :, 2] < 80)
    ys, xs = np.nonzero(green)
    assert abs(xs.min() - 40) <= 6 and abs(xs.max() - 119) <= 6 and abs(ys.max() - 159) <= 6


def test_detect_image_single_frame_threshold(image):
    frame = cv2.imread(str(image))
    cfg = HeatConfig().single_frame()
    windows, hm, boxes = detect_image(frame, FAKE, cfg)
    assert hm.config.n_frames == 1 and hm.config.threshold == cfg.single_frame_threshold
    assert len(windows) == 10 and windows.scale.tolist() == [1.0, 1.5, 2.0, 2.5, 3.0] * 2
    assert len(hm.blobs.boxes) == 2 and len(boxes.boxes) == 1  # the pole is filtered out
    x1, y1, x2, y2 = boxes.boxes[0]
    assert abs(x1 - 40) <= 4 and abs(x2 - 120) <= 4 and abs(y1 - 100) <= 4 and abs(y2 - 160) <= 4
    # a threshold above every heat value leaves nothing
    _, _, none = detect_image(frame, FAKE, HeatConfig().single_frame(1e6))
    assert len(none.boxes) == 0


def test_threshold_option(image, tmp_path, capsys):
    out = tmp_path / "o.png"
    assert imagecmd.run(parse(image, "-o", out, "--threshold", "1000"), detector=FAKE) == 0
    assert "0 vehicle(s)" in capsys.readouterr().out
    assert cv2.imread(str(out)).shape == (240, 320, 3)


def _main_fails(argv, capsys, match):
    rc = cli.main(["image", *map(str, argv)])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and match in err, err


def test_bad_inputs(image, tmp_path, capsys):
    notimg = tmp_path / "x.jpg"
    notimg.write_text("not an image")
    _main_fails([tmp_path / "missing.jpg", "-o", tmp_path / "o.jpg"], capsys, "file not found")
    _main_fails([notimg, "-o", tmp_path / "o.jpg"], capsys, "not an image")
    _main_fails([image, "-o", tmp_path / "nowhere" / "o.jpg"], capsys, "does not exist")
    _main_fails([image, "-o", image], capsys, "overwrite the input")
    _main_fails([image, "-o", tmp_path / "o.jpg", "--threshold", "-1"], capsys, "threshold")
    bad_model = tmp_path / "m.npz"
    bad_model.write_bytes(b"garbage")
    _main_fails([image, "-o", tmp_path / "o.jpg", "--model", bad_model], capsys, "m.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png", "m.npz", "x.jpg"]


def test_unwritable_extension(image, tmp_path):
    with pytest.raises(DataError, match="cannot write an image"):
        imagecmd.run(parse(image, "-o", tmp_path / "o.unknownext"), detector=FAKE)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]


def test_draw_helpers():
    img = np.zeros((100, 200, 3), np.uint8)
    draw.draw_boxes(img, np.array([[10, 20, 60, 80]]), np.array([3.25]))
    assert (img[20:80, 10] == draw.BOX_COLOR).all()
    assert draw.scale_color(1.0) != draw.scale_color(3.0)
    assert draw.scale_color(0.5) == draw.scale_color(1.0) and draw.scale_color(5) == draw.scale_color(3.0)
    heat = np.zeros((25, 50))
    heat[5:10, 5:20] = 3.0
    hi = draw.heat_image(heat)
    assert hi.shape == (25, 50, 3) and hi.dtype == np.uint8 and hi[0, 0].sum() < hi[7, 7].sum()
    big = draw.grid_to_frame(hi, 4, (98, 199))
    assert big.shape == (98, 199, 3) and (big[28, 28] == hi[7, 7]).all()
    labels = np.zeros((25, 50), np.int32)
    labels[5:10, 5:20] = 1
    li = draw.label_image(labels, mask=heat > 0)
    assert (li[7, 7] == draw.label_color(1)).all() and li[0, 0].sum() == 0
    frame = np.zeros((240, 320, 3), np.uint8)
    windows = Detections(np.array([[0, 0, 64, 64]]), np.array([1.0]), scale=np.array([1.0]))
    panels = draw.debug_panels(frame, windows, heat, labels, heat > 0, threshold=2.0)
    assert [p.shape for p in panels] == [(60, 80, 3)] * 3
    draw.paste_panels(frame, panels)
    assert frame[8:68, 8:88].any()


def test_draw_windows_colours_by_scale_and_part():
    """Each window is drawn in the colour of its scale (1 when the column is missing); the
    wide model's windows in that of the negated scale."""
    boxes = np.array([[0, 0, 20, 20], [30, 0, 50, 20], [60, 0, 80, 20]])
    img = np.zeros((40, 100, 3), np.uint8)
    w = Detections(boxes, np.ones(3), scale=np.array([1.0, 3.0, 3.0]), part=np.array([0, 0, WIDE_PART]))
    assert draw.draw_windows(img, w, 1) is img
    assert tuple(img[10, 0]) == draw.scale_color(1.0)
    assert tuple(img[10, 30]) == draw.scale_color(3.0)
    assert tuple(img[10, 60]) == draw.scale_color(-3.0)
    assert img[10, 10].sum() == 0  # inside a window: untouched
    img2 = np.zeros((40, 100, 3), np.uint8)
    draw.draw_windows(img2, Detections(boxes, np.ones(3)), 1, scale=0.5)
    assert tuple(img2[5, 9]) == draw.scale_color(1.0) and img2[5, 12].sum() == 0 and img2[15].sum() == 0

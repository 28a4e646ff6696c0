"""``python -m fastdet image`` with a fake detector (windows around bright regions), and its
bad-input errors (the drawing helpers it uses: tests/io/test_draw.py)."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet import cli
from fastdet.cli import image as imagecmd
from fastdet.cli.main import build_parser
from fastdet.config import HeatConfig
from fastdet.errors import DataError
from fastdet.video import detect_image
from tests.fakes import BlobsDetector


class FakePictures:
    """What ``image`` needs of a :class:`fastdet.video.picture.PictureDetector`, around a fake
    window detector (windows around each bright rectangle); its boxes are a single-frame heat
    map's (a fake's rule: the pole's windows make no box)."""

    kernels = ()

    def __init__(self, threshold=None):
        self.inner = BlobsDetector(score=2.0, scales=True)
        self.heat = HeatConfig().single_frame(threshold)
        self.shape = None

    def detector(self, shape):
        return self.inner

    def windows(self, img):
        self.shape = img.shape
        return self.inner.detect(img)

    def boxes_from_windows(self, windows):
        from fastdet.video import HeatMap

        return HeatMap(self.shape, self.heat, score_kind=self.inner.score_kind).update(windows)

    def second_stage(self, img, boxes):
        return boxes


FAKE = FakePictures()


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


def test_image_boxes_windows(image, tmp_path, capsys):
    out = tmp_path / "out.jpg"
    assert imagecmd.run(parse(image, "-o", out, "--windows"), detector=FAKE) == 0
    assert "1 vehicle(s) in 1 picture(s)" in capsys.readouterr().out
    res = cv2.imread(str(out))
    assert res.shape == (240, 320, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png", "out.jpg"]  # no partials
    # the final box is drawn in green around the vehicle
    green = (res[:, :, 1] > 200) & (res[:, :, 0] < 80) & (res[:, :, 2] < 80)
    ys, xs = np.nonzero(green)
    assert abs(xs.min() - 40) <= 6 and abs(xs.max() - 119) <= 6 and abs(ys.max() - 159) <= 6


def test_detect_image_single_frame_threshold(image):
    frame = cv2.imread(str(image))
    cfg = HeatConfig().single_frame()
    windows, hm, boxes = detect_image(frame, FAKE.inner, cfg)
    assert hm.config.n_frames == 1 and hm.config.threshold == cfg.single_frame_threshold
    assert len(windows) == 10 and windows.scale.tolist() == [1.0, 1.5, 2.0, 2.5, 3.0] * 2
    assert len(hm.blobs.boxes) == 2 and len(boxes.boxes) == 1  # the pole is filtered out
    x1, y1, x2, y2 = boxes.boxes[0]
    assert abs(x1 - 40) <= 4 and abs(x2 - 120) <= 4 and abs(y1 - 100) <= 4 and abs(y2 - 160) <= 4
    # a threshold above every heat value leaves nothing
    _, _, none = detect_image(frame, FAKE.inner, HeatConfig().single_frame(1e6))
    assert len(none.boxes) == 0


def test_a_picture_without_vehicles_is_still_written(image, tmp_path, capsys):
    out = tmp_path / "o.png"
    assert imagecmd.run(parse(image, "-o", out), detector=FakePictures(1000.0)) == 0
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
    bad_model = tmp_path / "m.npz"
    bad_model.write_bytes(b"garbage")
    _main_fails([image, "-o", tmp_path / "o.jpg", "--model", bad_model], capsys, "m.npz")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png", "m.npz", "x.jpg"]


def test_unwritable_extension(image, tmp_path):
    with pytest.raises(DataError, match="cannot write an image"):
        imagecmd.run(parse(image, "-o", tmp_path / "o.unknownext"), detector=FAKE)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.png"]


def test_folders_boxes_csv_and_out_dir(image, tmp_path, capsys):
    """PATH... with folders (recursive, sorted, names relative to the folder) and a file (its
    name as given); one CSV line a box after the header; annotated pictures under the same
    names; a picture that does not decode is skipped with one note and exit status 1."""
    src = tmp_path / "src"
    (src / "b").mkdir(parents=True)
    img = cv2.imread(str(image))
    cv2.imwrite(str(src / "b" / "two.png"), img)
    cv2.imwrite(str(src / "one.jpg"), img)
    (src / "b" / "broken.jpg").write_bytes(b"not a picture")
    (src / "notes.txt").write_text("not taken")
    csv, out = tmp_path / "boxes.csv", tmp_path / "out"
    rc = imagecmd.run(parse(src, image, "--boxes", csv, "-o", out, "--no-progress"), detector=FAKE)
    cap = capsys.readouterr()
    assert rc == imagecmd.SKIPPED_EXIT
    assert "skipped" in cap.err and "b/broken.jpg" in cap.err
    lines = csv.read_text().splitlines()
    assert lines[0] == "image,x1,y1,x2,y2,score"
    names = [ln.split(",")[0] for ln in lines[1:]]
    assert names == ["b/two.png", "one.jpg", str(image)]
    for ln in lines[1:]:
        x1, y1, x2, y2 = (int(v) for v in ln.split(",")[1:5])
        assert abs(x1 - 40) <= 6 and abs(x2 - 120) <= 6 and abs(y1 - 100) <= 6 and abs(y2 - 160) <= 6
    written = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file())
    assert written == ["b/two.png", "in.png", "one.jpg"]
    assert not [p for p in tmp_path.rglob(".*partial*")]


def test_a_fifo_and_a_symlink_loop_in_a_folder_are_named_and_counted(image, tmp_path, capsys):
    """A named pipe and a symlink loop with pictures' names inside a folder were passed over
    without a word (issue 34): each is now skipped with its own note naming it, counted in the
    "N of M skipped" line, exit status 1 as for a picture that does not decode; the FIFO is
    never opened (the run would wait on it)."""
    import os

    src = tmp_path / "src"
    src.mkdir()
    cv2.imwrite(str(src / "a.jpg"), cv2.imread(str(image)))
    os.mkfifo(src / "pipe.jpg")
    (src / "loop.png").symlink_to("loop.png")
    (src / "not-a-picture").symlink_to("not-a-picture")  # not a picture's name: not taken
    out = tmp_path / "out"
    rc = imagecmd.run(parse(src, "-o", out, "--no-progress"), detector=FAKE)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == imagecmd.SKIPPED_EXIT, err
    assert len(err) == 3, err
    assert "skipped" in err[0] and "loop.png: symlink loop" in err[0], err
    assert "skipped" in err[1] and "pipe.jpg: is a named pipe (FIFO)" in err[1], err
    assert "2 of 3 picture(s) skipped" in err[2] and "loop.png, pipe.jpg" in err[2], err
    assert [p.name for p in out.iterdir()] == ["a.jpg"]


def test_boxes_only_and_bad_runs(image, tmp_path, capsys):
    csv = tmp_path / "b.csv"
    assert imagecmd.run(parse(image, "--boxes", csv, "--no-progress"), detector=FAKE) == 0
    assert len(csv.read_text().splitlines()) == 2
    empty = tmp_path / "empty"
    empty.mkdir()
    _main_fails([empty, "--boxes", tmp_path / "c.csv"], capsys, "no pictures")
    _main_fails([image], capsys, "--boxes")
    _main_fails([image, "--boxes", tmp_path / "nowhere" / "c.csv"], capsys, "does not exist")
    assert not (tmp_path / "c.csv").exists()

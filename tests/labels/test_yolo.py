"""fastdet.labels.yolo: YOLO txt sets (idd_mini) and every way a YOLO file can be wrong."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.labels.yolo import parse_yolo, read_classes, read_yolo

from .synth import one_error, picture, write

CLASSES = "car\nbus\ntruck\nperson\nmotorbike\nbicycle\n"


def yolo_set(root: Path, labels: dict[str, str], width: int = 640, height: int = 360) -> Path:
    """``ROOT/classes.txt``, ``images/NAME.jpg`` and ``labels/NAME.txt`` for every entry."""
    write(root / "classes.txt", CLASSES)
    for name, text in labels.items():
        picture(root / "images" / f"{name}.jpg", width, height)
        write(root / "labels" / f"{name}.txt", text)
    return root


# ------------------------------------------------------------------------- the shared set


def test_idd_mini_counts(data):
    root = data / "frames" / "idd_mini"
    pics = read_yolo(root, complete=False)
    assert len(pics) == 300
    assert all(not p.complete and p.source == "idd_mini" for p in pics)
    vehicles = sum(len(p.targets) for p in pics)
    ignores = sum(len(p.ignores) for p in pics)
    assert vehicles + ignores == 595 + 149 + 233 + 22  # cars, buses, trucks (some small) + 22 bicycles
    assert vehicles > 500
    # class by class, through the parser on every real file: one class a vehicle, the others dropped
    files = sorted((root / "labels").rglob("*.txt"))
    for cls, count in ((0, 595), (1, 149), (2, 233), (3, 764), (5, 22)):
        kinds = [None] * 6
        kinds[cls] = True
        assert sum(len(parse_yolo(f.read_text(), str(f), kinds, 960, 720)) for f in files) == count


def test_idd_box_in_pixels(data):
    """The first line of a real file, by hand: 2 0.53515625 0.3995 0.0682 0.1935 on 1920 wide."""
    pics = read_yolo(data / "frames" / "idd_mini")
    pic = next(p for p in pics if p.name.endswith("BLR-2018-05-03_14-15-50_rearNear_left/0000465.jpg"))
    cx, cy, w, h = 0.53515625, 0.399537037037037, 0.06822916666666666, 0.1935185185185185
    want = [(cx - w / 2) * pic.width, (cy - h / 2) * pic.height, (cx + w / 2) * pic.width, (cy + h / 2) * pic.height]
    assert any(np.allclose(t, want) for t in pic.targets)


# ------------------------------------------------------------------------- conversion


@settings(max_examples=100, deadline=None)
@given(width=st.integers(64, 2000), height=st.integers(64, 2000),
       fx=st.floats(0, 0.9), fy=st.floats(0, 0.9), fw=st.floats(0.01, 1), fh=st.floats(0.01, 1))
def test_normalised_to_pixels_round_trip(width, height, fx, fy, fw, fh):
    x1, y1 = fx * width, fy * height
    x2, y2 = min(width, x1 + fw * width), min(height, y1 + fh * height)
    line = f"0 {(x1 + x2) / 2 / width!r} {(y1 + y2) / 2 / height!r} {(x2 - x1) / width!r} {(y2 - y1) / height!r}"
    (b,) = parse_yolo(line, "t.txt", [True], width, height)
    np.testing.assert_allclose([b.x1, b.y1, b.x2, b.y2], [x1, y1, x2, y2], atol=1e-9)
    assert b.vehicle and b.where == "t.txt: line 1"


def test_classes_vehicles_ignores_dropped(tmp_path):
    root = yolo_set(tmp_path / "s", {"a": "0 0.5 0.5 0.2 0.2\n3 0.5 0.5 0.1 0.3\n4 0.2 0.5 0.1 0.1\n\n"
                                          "5 0.8 0.5 0.1 0.1\n0 0.1 0.1 0.01 0.01\n",
                                     "b": "", "sub/c": "2 0.5 0.5 1.0 1.0\n"})
    picture(root / "images" / "d.png", 64, 64)  # no label file: nothing labelled (a background picture)
    pics = read_yolo(root, camera=lambda n: "cam-" + n)
    assert [p.name for p in pics] == ["a.jpg", "b.jpg", "d.png", "sub/c.jpg"]
    a = pics[0]
    np.testing.assert_allclose(a.targets, [[256, 144, 384, 216]])
    assert len(a.ignores) == 3  # motorbike, bicycle, the tiny car; the person is dropped
    assert pics[1].boxes.shape == (0, 4) and pics[2].boxes.shape == (0, 4) and pics[2].width == 64
    np.testing.assert_allclose(pics[3].targets, [[0, 0, 640, 360]])
    assert a.camera == "cam-a.jpg" and a.source == "s" and a.complete


def test_flat_layout(tmp_path):
    write(tmp_path / "classes.txt", CLASSES)
    picture(tmp_path / "x.jpg")
    write(tmp_path / "x.txt", "1 0.5 0.5 0.5 0.5\n")
    (pic,) = read_yolo(tmp_path, source="flat", camera="one")
    assert pic.targets.shape == (1, 4) and pic.camera == "one" and pic.source == "flat"


# ------------------------------------------------------------------------- malformed


def test_bad_lines(tmp_path):
    cases = {
        "fields": ("0 0.5 0.5 0.2\n", "expected 5 fields"),
        "segment": ("0 0.5 0.5 0.2 0.2 0.3 0.3\n", "expected 5 fields"),
        "number": ("0 0.5 abc 0.2 0.2\n", "cy is not a number: 'abc'"),
        "nan": ("0 0.5 nan 0.2 0.2\n", "not a finite number"),
        "class": ("6 0.5 0.5 0.2 0.2\n", "unknown class '6'"),
        "fraction": ("1.5 0.5 0.5 0.2 0.2\n", "unknown class '1.5'"),
        "negative": ("0 0.5 0.5 -0.2 0.2\n", "negative box size"),
        "outside": ("0 1.6 0.5 0.2 0.2\n", "entirely outside the 640x360 picture"),
    }
    for name, (text, words) in cases.items():
        root = yolo_set(tmp_path / name, {"ok": "0 0.5 0.5 0.2 0.2\n", "z": "0 0.5 0.5 0.2 0.2\n\n" + text})
        one_error(lambda r=root: read_yolo(r), root / "labels" / "z.txt", words, line=3)


def test_label_without_picture(tmp_path):
    root = yolo_set(tmp_path / "s", {"a": "0 0.5 0.5 0.2 0.2\n"})
    write(root / "labels" / "lost.txt", "0 0.5 0.5 0.2 0.2\n")
    one_error(lambda: read_yolo(root), root / "labels" / "lost.txt", "no picture for this label file")


def test_class_map_errors(tmp_path):
    root = yolo_set(tmp_path / "s", {"a": "0 0.5 0.5 0.2 0.2\n"})
    write(root / "classes.txt", "car\ncra\n")
    one_error(lambda: read_yolo(root), root / "classes.txt", "unknown class 'cra'", line=2)
    write(root / "classes.txt", "")
    one_error(lambda: read_classes(root / "classes.txt"), root / "classes.txt", "no class names")
    (root / "classes.txt").unlink()
    one_error(lambda: read_yolo(root), root / "classes.txt", "not found")


def test_empty_set_and_missing_folders(tmp_path):
    root = tmp_path / "empty"
    write(root / "classes.txt", CLASSES)
    (root / "images").mkdir()
    (root / "labels").mkdir()
    one_error(lambda: read_yolo(root), root / "images", "no pictures")
    (root / "labels").rmdir()
    one_error(lambda: read_yolo(root), root / "labels", "labels folder not found")
    one_error(lambda: read_yolo(tmp_path / "nowhere"), tmp_path / "nowhere", "not found")

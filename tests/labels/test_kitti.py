"""fastdet.labels.kitti: KITTI label_2 (kitti_tiny), the types' meaning, malformed files."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fastdet.labels import kitti
from fastdet.labels.kitti import read_kitti

from .synth import one_error, picture, write

TAIL = "1.5 1.6 3.9 1.0 1.7 20.0 0.1"


def line(kind: str, box: tuple[float, float, float, float], truncated: float = 0.0, occluded: int = 0) -> str:
    return f"{kind} {truncated} {occluded} -1.5 {box[0]} {box[1]} {box[2]} {box[3]} {TAIL}\n"


def kitti_set(root: Path, labels: dict[str, str], suffix: str = ".png") -> Path:
    for stem, text in labels.items():
        picture(root / "image_2" / f"{stem}{suffix}", 1242, 375)
        write(root / "label_2" / f"{stem}.txt", text)
    return root


def test_kitti_tiny_counts(data, monkeypatch):
    root = data / "frames" / "kitti_tiny"
    pics = read_kitti(root, camera="kitti")
    assert len(pics) == 101 and all(p.camera == "kitti" and p.complete for p in pics)
    # every Car, Van, Truck, DontCare, Cyclist, Tram, Misc line is a target or an ignore region
    assert sum(len(p.targets) + len(p.ignores) for p in pics) == 303 + 34 + 14 + 237 + 18 + 12 + 6
    # type by type: one type a vehicle, every other dropped
    for kind, count in (("car", 303), ("van", 34), ("truck", 14), ("dontcare", 237)):
        monkeypatch.setattr(kitti, "KITTI_TYPES", {**{k: None for k in kitti.KITTI_TYPES}, kind: False})
        assert sum(len(p.ignores) for p in read_kitti(root)) == count, kind


def test_types_truncation_occlusion(tmp_path):
    text = (line("Car", (100, 100, 300, 250)) + line("Van", (400, 100, 500, 250), truncated=0.6)
            + line("Truck", (600, 100, 800, 250), occluded=2) + line("Car", (850, 100, 950, 250), occluded=1)
            + line("Pedestrian", (0, 0, 50, 100)) + line("Person_sitting", (0, 0, 50, 100))
            + line("Tram", (10, 10, 20, 20)) + line("Cyclist", (10, 10, 20, 20)) + line("Misc", (10, 10, 20, 20))
            + "DontCare -1 -1 -10 503.89 169.71 590.61 190.13 -1 -1 -1 -1000 -1000 -1000 -10\n"
            + line("Car", (1210, 100, 1300, 250)))
    root = kitti_set(tmp_path / "s", {"000000": text}, suffix=".jpg")
    (pic,) = read_kitti(root)
    np.testing.assert_allclose(pic.targets, [[100, 100, 300, 250], [850, 100, 950, 250]])
    assert len(pic.ignores) == 2 + 3 + 1 + 1  # hidden van and truck; tram, cyclist, misc; dontcare; clipped car
    np.testing.assert_allclose(pic.ignores[-1], [1210, 100, 1242, 250])
    assert (pic.width, pic.height, pic.name) == (1242, 375, "000000.jpg")


def test_malformed(tmp_path):
    cases = {
        "fields": ("Car 0 0 -1.5 1 2 3\n", "expected 15 fields"),
        "class": (line("Bus", (1, 1, 100, 100)), "unknown class 'Bus'"),
        "number": (line("Car", (1, "x", 100, 100)), "top is not a number: 'x'"),
        "tail": (line("Car", (1, 1, 100, 100)).replace("20.0", "twenty"), "z is not a number"),
        "negative": (line("Car", (100, 1, 50, 100)), "negative box size"),
        "outside": (line("Car", (1300, 1, 1400, 100)), "entirely outside the 1242x375 picture"),
    }
    for name, (bad, words) in cases.items():
        root = kitti_set(tmp_path / name, {"a": line("Car", (1, 1, 100, 100)), "b": "\n" + bad})
        one_error(lambda r=root: read_kitti(r), root / "label_2" / "b.txt", words, line=2)


def test_missing_picture_folders_empty(tmp_path):
    root = kitti_set(tmp_path / "s", {"a": ""})
    write(root / "label_2" / "b.txt", "")
    one_error(lambda: read_kitti(root), root / "label_2" / "b.txt", "no picture")
    empty = tmp_path / "e"
    (empty / "label_2").mkdir(parents=True)
    one_error(lambda: read_kitti(empty), empty / "image_2", "folder not found")
    (empty / "image_2").mkdir()
    one_error(lambda: read_kitti(empty), empty / "label_2", "no KITTI label files")

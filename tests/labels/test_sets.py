"""fastdet.labels.sets: ``--frames FORMAT:PATH[,options]`` specs and the shared data's sets."""
from __future__ import annotations

from pathlib import Path

import pytest

from fastdet.labels.sets import FrameSpec, human_sets, parse_spec, read_spec, shared_sets, teacher_sets

from .synth import one_error, picture, write


@pytest.mark.parametrize("spec, want", [
    ("yolo:data/idd", FrameSpec("yolo", Path("data/idd"))),
    ("VOC:a b/c,positives-only", FrameSpec("voc", Path("a b/c"), complete=False)),
    ("coco:x.json, camera=cam 1 ", FrameSpec("coco", Path("x.json"), camera="cam 1")),
    ("teacher:d,min-score=0.5,positives-only", FrameSpec("teacher", Path("d"), complete=False, min_score=0.5)),
    ("mot:d/annotations/c.gt.txt,every=2", FrameSpec("mot", Path("d/annotations/c.gt.txt"), every=2)),
    ("kitti:C:/data/kitti", FrameSpec("kitti", Path("C:/data/kitti"))),
])
def test_parse(spec, want):
    assert parse_spec(spec) == want


@pytest.mark.parametrize("spec, words", [
    ("idd_mini", "expected FORMAT:PATH"),
    ("yaml:x", "FORMAT one of yolo, voc, coco, kitti, mot, teacher"),
    ("voc:", "no PATH after 'voc:'"),
    ("voc:x,postives-only", "unknown option 'postives-only' for voc (options: positives-only, camera=NAME)"),
    ("voc:x,min-score=0.5", "unknown option 'min-score=0.5' for voc"),
    ("voc:x,camera=", "unknown option 'camera='"),
    ("teacher:x,min-score=high", "min-score must be a number, got 'high'"),
    ("teacher:x,min-score=3", "min-score must be 0 to 1"),
    ("mot:x,every=0", "every must be a whole number >= 1"),
])
def test_bad_specs_are_one_line(spec, words):
    one_error(lambda: parse_spec(spec), f"--frames {spec}", words)


def test_read_spec(tmp_path):
    picture(tmp_path / "s" / "images" / "a.jpg")
    write(tmp_path / "s" / "voc" / "a.xml", "<annotation><object><name>car</name><bndbox><xmin>1</xmin>"
                                            "<ymin>1</ymin><xmax>100</xmax><ymax>80</ymax></bndbox></object></annotation>")
    (pic,) = read_spec(f"voc:{tmp_path / 's'},positives-only,camera=mine")
    assert not pic.complete and pic.camera == "mine" and pic.targets.shape == (1, 4)
    one_error(lambda: read_spec(f"kitti:{tmp_path / 's'}"), tmp_path / "s" / "label_2", "not found")


def test_specs_of_the_shared_data(data):
    assert len(read_spec(f"coco:{data / 'frames' / 'dawn_weather' / 'instances.json'},positives-only")) == 148
    assert len(read_spec(f"mot:{data},every=1")) == 38 + 88 + 30 + 8 + 14
    strict = read_spec(f"teacher:{data / 'teacher' / 'tmo_night.teacher.txt'},min-score=0.9")
    assert len(strict) == 216 and sum(len(p.targets) for p in strict) < 36


def test_shared_sets(data):
    sets = shared_sets(data)
    humans, teachers = human_sets(sets), teacher_sets(sets)
    assert list(humans) == ["dawn_fog", "dawn_weather", "idd_mini", "kitti_tiny", "boston_street", "highway_640",
                            "motorcycle_highway", "test_small1", "test_video"]
    assert len(teachers) == 17 and set(humans) | set(teachers) == set(sets)
    assert all(k.startswith("teacher:") and all(p.camera == k for p in v) for k, v in teachers.items())
    sizes = {k: len(v) for k, v in humans.items()}
    assert sizes == {"dawn_fog": 156, "dawn_weather": 148, "idd_mini": 300, "kitti_tiny": 101, "boston_street": 8,
                     "highway_640": 30, "motorcycle_highway": 14, "test_small1": 18, "test_video": 8}
    complete = {k: {p.complete for p in v} for k, v in sets.items()}
    assert complete.pop("dawn_weather") == {False} and complete.pop("idd_mini") == {False}
    assert all(c == {True} for c in complete.values())
    cameras = {k: {p.camera for p in v} for k, v in humans.items()}
    assert len(cameras["dawn_fog"]) == 156 and "dawn_fog/foggy-001" in cameras["dawn_fog"]
    assert len(cameras["dawn_weather"]) == 148 and "dawn_weather/dusttornado-006" in cameras["dawn_weather"]
    assert cameras["idd_mini"] == {f"idd_mini/{c}" for c in ("frontFar", "frontNear", "sideLeft", "sideRight",
                                                             "rearNear", "highquality_16k")}
    assert cameras["kitti_tiny"] == {"kitti"}
    assert cameras["test_video"] == cameras["test_small1"] == {"udacity"}
    assert cameras["highway_640"] == {"clip:highway_640"}
    assert all(p.source == k for k, v in sets.items() for p in v)


def test_shared_sets_of_a_missing_folder(tmp_path):
    one_error(lambda: shared_sets(tmp_path / "none"), tmp_path / "none", "data folder not found")

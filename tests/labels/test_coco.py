"""fastdet.labels.coco: COCO instances json (dawn_weather, partial labels) and malformed files."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fastdet.labels.coco import read_coco

from .synth import one_error, picture, write

CATS = [{"id": 1, "name": "Car"}, {"id": 2, "name": "person"}, {"id": 3, "name": "motorcycle"}]


def coco_set(root: Path, doc: dict | str, pictures: tuple[str, ...] = ("a.jpg", "b.jpg")) -> Path:
    for name in pictures:
        picture(root / "images" / name)
    write(root / "instances.json", doc if isinstance(doc, str) else json.dumps(doc))
    return root


def doc(annotations: list[dict], images: list[dict] | None = None, categories: list[dict] | None = None) -> dict:
    images = images if images is not None else [
        {"id": 1, "file_name": "a.jpg", "width": 640, "height": 360},
        {"id": 2, "file_name": "b.jpg", "width": 640, "height": 360}]
    return {"images": images, "annotations": annotations, "categories": CATS if categories is None else categories}


def ann(image_id: int = 1, cat: int = 1, bbox: list | None = None, **kw) -> dict:
    return {"id": 9, "image_id": image_id, "category_id": cat, "bbox": bbox or [10, 20, 100, 50], **kw}


def test_dawn_weather_counts(data):
    root = data / "frames" / "dawn_weather"
    pics = read_coco(root, complete=False)
    assert len(pics) == 148 and sum(len(p.targets) + len(p.ignores) for p in pics) == 298
    assert all(not p.complete for p in pics)
    assert read_coco(root / "instances.json", complete=False)[0].path == pics[0].path  # the json itself


def test_boxes_classes_crowds(tmp_path):
    anns = [ann(), ann(cat=2), ann(cat=3, bbox=[300, 100, 50, 80]), ann(bbox=[400, 100, 200, 100], iscrowd=1),
            ann(image_id=2, bbox=[0, 0, 10, 10])]
    root = coco_set(tmp_path / "s", doc(anns))
    a, b = read_coco(root)
    np.testing.assert_allclose(a.targets, [[10, 20, 110, 70]])
    np.testing.assert_allclose(a.ignores, [[300, 100, 350, 180], [400, 100, 600, 200]])
    assert b.targets.shape == (0, 4) and b.ignores.shape == (1, 4)  # too small
    assert a.name == "a.jpg" and a.source == "s" and a.camera == "s"


def test_pictures_beside_the_json_without_sizes(tmp_path):
    picture(tmp_path / "x.png", 100, 80)
    write(tmp_path / "my.json", json.dumps(doc([], images=[{"id": 5, "file_name": "x.png"}])))
    (pic,) = read_coco(tmp_path / "my.json", source="mine")
    assert (pic.width, pic.height, pic.source) == (100, 80, "mine")


def test_malformed(tmp_path):
    cases = {
        "json": ('{"images": [\n  {"id": 1,}\n]}', "not valid json (line 2: "),
        "notobject": ("[1, 2]", "expected a COCO json object"),
        "noimages": (json.dumps({"annotations": [], "categories": CATS}), "'images' must be a list"),
        "category": (doc([ann(cat=7)]), "annotations[0]: unknown class: category_id 7"),
        "catname": (doc([], categories=[{"id": 1, "name": "Carr"}]), "categories[0]: unknown class 'Carr'"),
        "image": (doc([ann(), ann(image_id=3)]), "annotations[1]: image_id 3 is not in 'images'"),
        "bbox": (doc([ann(bbox=[1, 2, 3])]), "annotations[0]: bbox must be [x, y, width, height]"),
        "number": (doc([ann(bbox=[1, "2", 3, 4])]), "annotations[0]: bbox must be a finite number, got \"2\""),
        "negative": (doc([ann(bbox=[10, 10, -5, 4])]), "annotations[0]: negative box size"),
        "outside": (doc([ann(bbox=[700, 10, 50, 40])]), "annotations[0]: the box"),
        "size": (doc([], images=[{"id": 1, "file_name": "a.jpg", "width": 641, "height": 360}]),
                 "images[0]: says 641x360, the picture a.jpg is 640x360"),
        "twice": (doc([], images=[{"id": 1, "file_name": "a.jpg"}, {"id": 1, "file_name": "b.jpg"}]),
                  "images[1]: image id 1 is used twice"),
        "missing": (doc([], images=[{"id": 1, "file_name": "c.jpg"}]), "images[0]: the picture"),
        "empty": (doc([], images=[]), "no images in the COCO json"),
        # issue 34's walk: a RecursionError and a ValueError traceback before
        "deep": ("[" * 200_000, "not valid json (nested too deeply)"),
        "longint": (json.dumps(doc([], images=[{"id": 7, "file_name": "a.jpg"}])).replace('"id": 7',
                                                                                           '"id": ' + "9" * 5000),
                    "not valid json (a number too long"),
    }
    for name, (text, words) in cases.items():
        root = coco_set(tmp_path / name, text)
        one_error(lambda r=root: read_coco(r), root / "instances.json", words)
    one_error(lambda: read_coco(tmp_path / "nowhere"), tmp_path / "nowhere", "COCO json not found")


def test_a_file_name_outside_the_set_is_refused(tmp_path):
    """A ``file_name`` leading out of the picture folder (``../x.jpg``, an absolute path) named a
    picture elsewhere on the machine, which was read as the set's (issue 34); now one line naming
    the json and the entry."""
    outside = picture(tmp_path / "elsewhere.jpg")
    for k, name in enumerate(("../../elsewhere.jpg", str(outside), "a/../../elsewhere.jpg", "/etc/hostname")):
        root = coco_set(tmp_path / f"s{k}", doc([], images=[{"id": 1, "file_name": "a.jpg"},
                                                           {"id": 2, "file_name": name}]))
        one_error(lambda r=root: read_coco(r), root / "instances.json", f"images[1]: file_name \"{name}\"",
                  "outside the set's picture folder", "labels must describe pictures of the set")
    root = coco_set(tmp_path / "in", doc([], images=[{"id": 1, "file_name": "x/../a.jpg"}]))
    assert [p.name for p in read_coco(root)] == ["x/../a.jpg"]

"""COCO instances json: one file for the whole set::

    {"images": [{"id": 1, "file_name": "a.jpg", "width": 592, "height": 366}, ...],
     "annotations": [{"id": 1, "image_id": 1, "category_id": 1, "bbox": [x, y, w, h],
                      "iscrowd": 0}, ...],
     "categories": [{"id": 1, "name": "Car"}, ...]}

Layout (the shared ``dawn_weather``)::

    ROOT/instances.json
    ROOT/images/FILE_NAME

``PATH`` may be the json file itself; its pictures are then in ``images/`` beside it (or
beside it, when there is no ``images/`` folder). Every entry of ``images`` is a picture (one
without annotations has no labelled object). A picture's size is read from its header; a
``width``/``height`` in the json that says otherwise is a :class:`~fastdet.errors.DataError`.
Category names are read by :func:`~fastdet.labels.rules.class_kind`; an ``iscrowd`` box of
vehicles is an ignore region; then the rules of :mod:`fastdet.labels.rules`.

json has no useful line numbers (the shared file is one line), so errors name the entry:
``instances.json: annotations[17]: ...``.
"""
from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import DataError
from ..io.files import JsonError, not_found, parse_json
from .imagesize import image_size
from .picture import AnnotatedPicture
from .rules import Box, camera_for, class_kind, make_picture, not_empty, picture_in, read_text

#: the json's file name in a set's folder
INSTANCES_FILE = "instances.json"


def _num(v: Any, what: str, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise DataError(f"{where}: {what} must be a finite number, got {json.dumps(v)[:40]}")
    return float(v)


def _int(v: Any, what: str, where: str) -> int:
    f = _num(v, what, where)
    if f != int(f):
        raise DataError(f"{where}: {what} must be a whole number, got {v!r}")
    return int(f)


def _list(doc: dict[str, Any], key: str, source: str, required: bool = True) -> list[Any]:
    v = doc.get(key)
    if v is None and not required:
        return []
    if not isinstance(v, list):
        raise DataError(f"{source}: '{key}' must be a list" + ("" if key in doc else f" (there is no '{key}')"))
    return v


def _entry(v: Any, where: str) -> dict[str, Any]:
    if not isinstance(v, dict):
        raise DataError(f"{where}: expected an object, got {json.dumps(v)[:40]}")
    return v


def _paths(path: Path) -> tuple[Path, Path]:
    if path.is_dir():
        path = path / INSTANCES_FILE
    if not path.is_file():
        raise not_found(path, f"{path}: COCO json not found")
    images = path.parent / "images"
    return path, images if images.is_dir() else path.parent


def read_coco(path: str | Path, *, source: str | None = None, camera: str | Callable[[str], str] | None = None,
              complete: bool = True, images: str | Path | None = None) -> list[AnnotatedPicture]:
    """Every picture of the COCO set at ``path`` (a folder holding ``instances.json``, or the
    json; layout in the module docstring), in the json's order; ``source`` (default: the
    folder's name), ``camera``, ``complete`` as :func:`~fastdet.labels.yolo.read_yolo`'s (the
    picture's name is its ``file_name``); ``images``: the picture folder, when it is not the
    default. Raises DataError on the first error of the whole set."""
    json_path, image_dir = _paths(Path(path))
    if images is not None:
        image_dir = Path(images)
    source = source or json_path.parent.name
    src = str(json_path)
    try:
        doc = parse_json(read_text(json_path, "COCO json"))
    except JsonError as exc:
        raise DataError(f"{src}: not valid json ({exc})") from None
    if not isinstance(doc, dict):
        raise DataError(f"{src}: expected a COCO json object with 'images', 'annotations', 'categories'")

    kinds: dict[int, bool | None] = {}
    for k, c in enumerate(_list(doc, "categories", src)):
        where = f"{src}: categories[{k}]"
        c = _entry(c, where)
        name = c.get("name")
        if not isinstance(name, str):
            raise DataError(f"{where}: a category needs a 'name'")
        kinds[_int(c.get("id"), "id", where)] = class_kind(name, where)

    entries: dict[int, tuple[str, int, int, str, Path]] = {}  # id -> file_name, width, height, where, picture
    for k, im in enumerate(_list(doc, "images", src)):
        where = f"{src}: images[{k}]"
        im = _entry(im, where)
        iid = _int(im.get("id"), "id", where)
        if iid in entries:
            raise DataError(f"{where}: image id {iid} is used twice (first in {entries[iid][3]})")
        fn = im.get("file_name")
        if not isinstance(fn, str) or not fn:
            raise DataError(f"{where}: an image needs a 'file_name'")
        p = picture_in(image_dir, fn, where, f"file_name {json.dumps(fn)}")  # not a picture outside the set
        w = _int(im["width"], "width", where) if "width" in im else 0
        h = _int(im["height"], "height", where) if "height" in im else 0
        entries[iid] = (fn, w, h, where, p)

    boxes: dict[int, list[Box]] = {iid: [] for iid in entries}
    for k, a in enumerate(_list(doc, "annotations", src, required=False)):
        where = f"{src}: annotations[{k}]"
        a = _entry(a, where)
        iid = _int(a.get("image_id"), "image_id", where)
        if iid not in entries:
            raise DataError(f"{where}: image_id {iid} is not in 'images'")
        cid = _int(a.get("category_id"), "category_id", where)
        if cid not in kinds:
            raise DataError(f"{where}: unknown class: category_id {cid} is not in 'categories'")
        bbox = a.get("bbox")
        if not isinstance(bbox, list) or len(bbox) != 4:
            raise DataError(f"{where}: bbox must be [x, y, width, height], got {json.dumps(bbox)[:60]}")
        bx, by, bw, bh = (_num(v, "bbox", where) for v in bbox)
        kind = kinds[cid]
        if kind is None:
            continue
        crowd = a.get("iscrowd", 0) not in (0, False, None)
        boxes[iid].append(Box(bx, by, bx + bw, by + bh, kind and not crowd, where))

    pictures = []
    for iid, (fn, w, h, where, p) in entries.items():
        if not p.is_file():
            raise DataError(f"{where}: the picture {p} is not there")
        width, height = image_size(p)
        if (w, h) != (0, 0) and (w, h) != (width, height):
            raise DataError(f"{where}: says {w}x{h}, the picture {fn} is {width}x{height}")
        pictures.append(make_picture(source=source, camera=camera_for(camera, source, fn), name=fn, path=p,
                                     width=width, height=height, boxes=boxes[iid], complete=complete))
    return not_empty(pictures, json_path, "images in the COCO json")

"""KITTI object labels (``label_2``): one ``.txt`` file per picture, one object a line of 15
fields separated by spaces (16 with a detector's score, which is not read)::

    type truncated occluded alpha left top right bottom height width length x y z rotation_y

``left top right bottom`` is the 2-D box in pixels (continuous, 0-based). ``truncated`` is a
fraction 0..1 of the object leaving the picture; ``occluded`` is 0 fully visible, 1 partly,
2 largely occluded, 3 unknown (-1 for ``DontCare``).

Layout (the shared ``kitti_tiny``, and KITTI's ``training/``)::

    ROOT/label_2/NAME.txt
    ROOT/image_2/NAME.png      (or .jpg, any picture suffix)

The label files make the set (a picture without one is not read); a label file without its
picture is a :class:`~fastdet.errors.DataError`.

What the types mean (decided here, see ``docs/labels.md``):

- ``Car``, ``Van``, ``Truck``: vehicles -- but one more than half out of the picture
  (``truncated`` > 0.5) or largely hidden (``occluded`` >= 2: largely occluded or unknown) is an
  ignore region, as the data README asks of a target to be at least half in view;
- ``Tram`` (rails, not road), ``Cyclist``, ``Misc`` (trailers, segways, ...) and ``DontCare``
  (KITTI's own ignore regions): ignore regions;
- ``Pedestrian``, ``Person_sitting``: dropped (not vehicles);
- any other type is refused (DataError naming the file and the line).

Then the rules of :mod:`fastdet.labels.rules` (size rule, clipping, boxes outside the picture).
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..errors import DataError
from .imagesize import IMAGE_SUFFIXES, image_size
from .picture import AnnotatedPicture
from .rules import Box, camera_for, check_folder, make_picture, normal_name, not_empty, number, read_text, text_lines

#: a vehicle more than this fraction out of the picture is an ignore region
MAX_TRUNCATED = 0.5
#: a vehicle with an ``occluded`` level at least this (2 largely occluded, 3 unknown) is an ignore region
MIN_OCCLUDED_IGNORED = 2

#: KITTI's object types: True a vehicle, False an ignore region, None dropped
KITTI_TYPES: dict[str, bool | None] = {
    "car": True, "van": True, "truck": True,
    "tram": False, "cyclist": False, "misc": False, "dontcare": False,
    "pedestrian": None, "person sitting": None,
}


def parse_kitti(text: str, source: str) -> list[Box]:
    """The boxes of one KITTI label file's ``text`` (pixels; dropped types left out);
    ``source`` names the file in errors."""
    boxes: list[Box] = []
    for where, line in text_lines(text, source):
        fields = line.split()
        if len(fields) not in (15, 16):
            raise DataError(f"{where}: expected 15 fields (16 with a score), got {len(fields)}: {line[:60]!r}")
        kind = KITTI_TYPES.get(normal_name(fields[0]), "unknown")
        if kind == "unknown":
            raise DataError(f"{where}: unknown class {fields[0][:40]!r} (KITTI types: Car, Van, Truck, Pedestrian, "
                            f"Person_sitting, Cyclist, Tram, Misc, DontCare)")
        truncated = number(fields[1], "truncated", where)
        occluded = number(fields[2], "occluded", where)
        x1, y1, x2, y2 = (number(f, n, where) for f, n in zip(fields[4:8], ("left", "top", "right", "bottom")))
        for f, n in zip(fields[8:], ("height", "width", "length", "x", "y", "z", "rotation_y", "score")):
            number(f, n, where)
        if kind is None:
            continue
        hidden = truncated > MAX_TRUNCATED or occluded >= MIN_OCCLUDED_IGNORED
        boxes.append(Box(x1, y1, x2, y2, bool(kind) and not hidden, where))
    return boxes


def _image_for(label: Path, images: Path) -> Path:
    for suffix in IMAGE_SUFFIXES:
        p = images / (label.stem + suffix)
        if p.is_file():
            return p
    raise DataError(f"{label}: no picture {images / label.stem}.* for this label file")


def read_kitti(root: str | Path, *, source: str | None = None, camera: str | Callable[[str], str] | None = None,
               complete: bool = True) -> list[AnnotatedPicture]:
    """Every picture of the KITTI set at ``root`` (layout in the module docstring), in the
    order of the sorted label names; ``source``, ``camera``, ``complete`` as
    :func:`~fastdet.labels.yolo.read_yolo`'s (the picture's name is its file name). Raises
    DataError on the first error of the whole set."""
    root = check_folder(Path(root), "KITTI set")
    source = source or root.name
    labels = check_folder(root / "label_2", "KITTI label_2")
    images = check_folder(root / "image_2", "KITTI image_2")
    pictures = []
    for label in sorted(labels.glob("*.txt")):
        boxes = parse_kitti(read_text(label), str(label))
        path = _image_for(label, images)
        width, height = image_size(path)
        pictures.append(make_picture(source=source, camera=camera_for(camera, source, path.name), name=path.name,
                                     path=path, width=width, height=height, boxes=boxes, complete=complete))
    return not_empty(pictures, labels, "KITTI label files")

"""YOLO txt labels: one ``.txt`` file per picture, one box a line::

    class cx cy w h

``class`` is a whole number indexing the class map (``classes.txt``: one class name a line,
the first is class 0); ``cx cy w h`` are the box's centre and size as fractions of the
picture's width and height. The picture's size comes from its file header
(:func:`~fastdet.labels.imagesize.image_size`), so no picture is decoded.

Layout (the shared ``idd_mini``, and Ultralytics' own)::

    ROOT/classes.txt
    ROOT/images/**/NAME.jpg        (any of .jpg .jpeg .png .bmp .webp .tif .tiff)
    ROOT/labels/**/NAME.txt        (the same relative path)

or a flat folder holding the pictures, their ``.txt`` files and ``classes.txt`` side by side.
A picture without a label file has no labelled object (the YOLO convention for background
pictures); a label file without its picture is a :class:`~fastdet.errors.DataError`.

Class names are read by :func:`~fastdet.labels.rules.class_kind`: vehicles (car, bus,
truck, ...) are targets, two-wheelers ignore regions, persons and other known classes are
dropped; the rules of :mod:`fastdet.labels.rules` (size rule, clipping, boxes outside the
picture) apply. A line that is not five numbers, a class that is not a whole number or not in
the class map, or a negative size raises a DataError naming the file and the line.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..errors import DataError
from .imagesize import IMAGE_SUFFIXES, image_size
from .picture import AnnotatedPicture
from .rules import Box, camera_for, check_folder, class_kind, make_picture, not_empty, number, read_text, text_lines

#: the class map's file name
CLASSES_FILE = "classes.txt"


def read_classes(path: Path) -> list[bool | None]:
    """The class map ``path`` (one name a line) as what each class id means: True a vehicle,
    False an ignore region, None dropped. DataError for a missing or empty file, or a name
    :func:`~fastdet.labels.rules.class_kind` does not know (naming the line)."""
    text = read_text(path, "class map (classes.txt)")
    kinds: list[bool | None] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        name = raw.strip()
        if not name:
            raise DataError(f"{path}: line {lineno}: empty class name (class {len(kinds)})")
        kinds.append(class_kind(name, f"{path}: line {lineno}"))
    if not kinds:
        raise DataError(f"{path}: no class names")
    return kinds


def parse_yolo(text: str, source: str, kinds: list[bool | None], width: int, height: int) -> list[Box]:
    """The boxes of one YOLO label file's ``text`` in pixels of a ``width x height`` picture
    (dropped classes left out); ``source`` names the file in errors."""
    boxes: list[Box] = []
    for where, line in text_lines(text, source):
        fields = line.split()
        if len(fields) != 5:
            raise DataError(f"{where}: expected 5 fields 'class cx cy w h', got {len(fields)}: {line[:60]!r}")
        cls = number(fields[0], "class", where)
        if cls != int(cls) or not 0 <= cls < len(kinds):
            raise DataError(f"{where}: unknown class {fields[0]!r} (the class map has classes 0 to "
                            f"{len(kinds) - 1})")
        cx, cy, w, h = (number(f, n, where) for f, n in zip(fields[1:], ("cx", "cy", "w", "h")))
        if w < 0 or h < 0:
            raise DataError(f"{where}: negative box size w={fields[3]} h={fields[4]}")
        kind = kinds[int(cls)]
        if kind is None:
            continue
        boxes.append(Box((cx - w / 2) * width, (cy - h / 2) * height, (cx + w / 2) * width,
                         (cy + h / 2) * height, kind, where))
    return boxes


def _folders(root: Path) -> tuple[Path, Path]:
    images, labels = root / "images", root / "labels"
    if images.is_dir() or labels.is_dir():
        return check_folder(images, "images"), check_folder(labels, "labels")
    return root, root


def read_yolo(root: str | Path, *, source: str | None = None, camera: str | Callable[[str], str] | None = None,
              complete: bool = True, classes: str | Path | None = None) -> list[AnnotatedPicture]:
    """Every picture of the YOLO set at ``root`` (layout in the module docstring), sorted by
    name (its path relative to the image folder, ``/``-separated).

    source: the set's name (default: ``root``'s folder name); camera: one camera id for every
    picture, or a function of the picture's name (default: ``source``); complete: whether
    every vehicle in a picture is labelled (False: positives only); classes: the class map
    (default ``ROOT/classes.txt``). Raises DataError on the first error of the whole set.
    """
    root = check_folder(Path(root), "YOLO set")
    source = source or root.name
    images_dir, labels_dir = _folders(root)
    kinds = read_classes(Path(classes) if classes is not None else root / CLASSES_FILE)
    images = {p.relative_to(images_dir).with_suffix(""): p for p in sorted(images_dir.rglob("*"))
              if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()}
    labels = {p.relative_to(labels_dir).with_suffix(""): p for p in sorted(labels_dir.rglob("*.txt"))
              if p.name != CLASSES_FILE or p.parent != root}
    for stem, label in labels.items():
        if stem not in images:
            raise DataError(f"{label}: no picture for this label file (looked for "
                            f"{images_dir / stem}{{{','.join(IMAGE_SUFFIXES)}}})")
    pictures = []
    for stem in sorted(images):
        path = images[stem]
        width, height = image_size(path)
        lab = labels.get(stem)
        boxes = [] if lab is None else parse_yolo(read_text(lab), str(lab), kinds, width, height)
        name = path.relative_to(images_dir).as_posix()
        pictures.append(make_picture(source=source, camera=camera_for(camera, source, name), name=name,
                                     path=path, width=width, height=height, boxes=boxes, complete=complete))
    return not_empty(pictures, images_dir, "pictures in the YOLO set")

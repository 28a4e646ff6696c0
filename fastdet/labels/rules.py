"""The rules every label reader applies, in one place (the data README's target / ignore rule).

A reader collects the boxes of one picture as it reads them -- each a :class:`Box`: its
``x1, y1, x2, y2`` in the picture's pixels, whether it is a vehicle or an ignore region, and
where it was read (``"FILE: line N"``) -- and :func:`make_picture` turns them into an
:class:`~fastdet.labels.picture.AnnotatedPicture`:

- a box that is not four finite numbers, or whose size is negative (``x2 < x1`` or
  ``y2 < y1``), is a :class:`~fastdet.errors.DataError` naming where it was read;
- a box that lies entirely outside the picture (no area in common with it) is a DataError
  too: it belongs to another picture or another picture size;
- a box of zero width or height (a click, not a box) is dropped: it marks nothing. Every
  other box overlaps the picture, so it keeps a positive size once clipped;
- boxes are clipped to the picture (``0 <= x <= width``, ``0 <= y <= height``);
- a vehicle narrower than 1/32 of the picture's width or than 24 px *after clipping* (what
  is in view) is an ignore region (:func:`~fastdet.labels.picture.split_small`).
"""
from __future__ import annotations

import math
import os
import posixpath
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..io.files import read_input_text
from .picture import AnnotatedPicture, split_small


@dataclass(frozen=True)
class Box:
    """One labelled box as read: ``x1, y1, x2, y2`` in pixels of the picture (continuous
    coordinates, ``x2 = left + width``); ``vehicle`` (a target unless too small) or an ignore
    region; ``where`` names the file and line it came from (``"a.txt: line 3"``)."""

    x1: float
    y1: float
    x2: float
    y2: float
    vehicle: bool
    where: str


def ltwh_box(left: float, top: float, width: float, height: float, vehicle: bool, where: str) -> Box:
    """A :class:`Box` from ``left, top, width, height`` (pixels)."""
    return Box(left, top, left + width, top + height, vehicle, where)


def check_box(box: Box, width: int, height: int) -> bool:
    """Whether ``box`` is kept (False: zero width or height, dropped); DataError for a box
    that is not finite, has a negative size or lies entirely outside the ``width x height``
    picture."""
    coords = (box.x1, box.y1, box.x2, box.y2)
    if not all(math.isfinite(v) for v in coords):
        raise DataError(f"{box.where}: the box is not four finite numbers: {coords}")
    if box.x2 < box.x1 or box.y2 < box.y1:
        raise DataError(f"{box.where}: negative box size (x1={box.x1:g} y1={box.y1:g} x2={box.x2:g} "
                        f"y2={box.y2:g})")
    if box.x2 == box.x1 or box.y2 == box.y1:
        return False
    if box.x2 <= 0 or box.y2 <= 0 or box.x1 >= width or box.y1 >= height:
        raise DataError(f"{box.where}: the box x1={box.x1:g} y1={box.y1:g} x2={box.x2:g} y2={box.y2:g} "
                        f"lies entirely outside the {width}x{height} picture")
    return True


def _array(boxes: Sequence[Box], width: int, height: int) -> np.ndarray:
    if not boxes:
        return np.zeros((0, 4), np.float64)
    b = np.array([(x.x1, x.y1, x.x2, x.y2) for x in boxes], np.float64)
    np.clip(b[:, 0::2], 0.0, float(width), out=b[:, 0::2])
    np.clip(b[:, 1::2], 0.0, float(height), out=b[:, 1::2])
    return b


def apply_rules(boxes: Iterable[Box], width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """``(targets (N, 4), ignores (M, 4))`` float64 x1y1x2y2 of one ``width x height``
    picture by the module's rules (DataError on the first bad box, in reading order)."""
    kept = [b for b in boxes if check_box(b, width, height)]
    vehicles = _array([b for b in kept if b.vehicle], width, height)
    ignores = _array([b for b in kept if not b.vehicle], width, height)
    targets, small = split_small(vehicles, width)
    return targets, np.concatenate([ignores, small])


def make_picture(*, source: str, camera: str, name: str, path: Path, width: int, height: int,
                 boxes: Iterable[Box], complete: bool, frame: int | None = None,
                 labelled_by: str = "human") -> AnnotatedPicture:
    """An :class:`AnnotatedPicture` of ``boxes`` by :func:`apply_rules`."""
    targets, ignores = apply_rules(boxes, width, height)
    return AnnotatedPicture(source=source, camera=camera, name=name, path=path, width=width, height=height,
                            targets=targets, ignores=ignores, complete=complete, frame=frame,
                            labelled_by=labelled_by)


def number(text: str, what: str, where: str) -> float:
    """``text`` as a finite float; DataError ``"WHERE: WHAT is not a number: 'TEXT'"``."""
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise DataError(f"{where}: {what} is not a number: {str(text)[:40]!r}") from None
    if not math.isfinite(v):
        raise DataError(f"{where}: {what} is not a finite number: {str(text)[:40]!r}")
    return v


def read_text(path: Path, what: str = "label file") -> str:
    """The text of ``path`` (UTF-8, a BOM allowed); DataError for a missing, unreadable or
    binary file."""
    if path.is_dir():
        raise DataError(f"{path}: is a folder, expected a {what}")
    if not path.exists() and not path.is_symlink():
        raise DataError(f"{path}: {what} not found")
    return read_input_text(path, what)


def check_folder(path: Path, what: str) -> Path:
    """``path`` if it is a folder; DataError naming it otherwise."""
    if not path.is_dir():
        raise DataError(f"{path}: " + (f"is a file, expected the {what} folder" if path.exists()
                                       else f"{what} folder not found"))
    return path


def picture_in(folder: Path, name: str, where: str, entry: str) -> Path:
    """``folder / name`` (``name`` normalised: ``a/../b.jpg`` is ``b.jpg``), the picture a label
    entry names (a VOC ``<filename>``, a COCO ``file_name``), when ``name`` is a relative path
    that stays inside ``folder``; a
    :class:`DataError` naming ``where`` (the file, and the entry: ``images[3]``) and ``entry``
    (how the name was written) when it leads out of it -- an absolute path, ``../x.jpg``,
    ``a/../../x.jpg``: labels must describe pictures of the set, and a label file is not a way
    to have any file of the machine read. Checked on the name as written (a symlink inside the
    folder to pictures kept elsewhere is the set's own business)."""
    norm = posixpath.normpath(name.replace(os.sep, "/"))
    if posixpath.isabs(norm) or os.path.isabs(name) or norm == ".." or norm.startswith("../"):
        raise DataError(f"{where}: {entry} names a picture outside the set's picture folder {folder} "
                        f"(labels must describe pictures of the set)")
    return folder / norm


def not_empty(pictures: list[AnnotatedPicture], where: Path, what: str) -> list[AnnotatedPicture]:
    """``pictures``; DataError ``"WHERE: no WHAT"`` when there are none (an empty set is a
    mistake: a wrong folder, a wrong format)."""
    if not pictures:
        raise DataError(f"{where}: no {what}")
    return pictures


# ------------------------------------------------------------------------- class names

#: class names that are vehicles to find (after :func:`normal_name`)
VEHICLE_NAMES = frozenset({
    "car", "van", "truck", "bus", "pickup", "pickup truck", "suv", "lorry", "minivan", "minibus", "coach",
    "jeep", "taxi", "autorickshaw", "auto rickshaw", "three wheeler", "vehicle",
})
#: class names that are ignore regions: two-wheelers (data README), a format's own "don't care",
#: rail and farm vehicles and trailers (vehicles a road detector is not asked to find)
IGNORE_NAMES = frozenset({
    "motorcycle", "motorbike", "motor", "bicycle", "bike", "cyclist", "scooter", "moped", "rider on motorcycle",
    "dontcare", "dont care", "ignore", "ignored", "misc", "tram", "train", "tractor", "trailer", "caravan",
    "other vehicle",
})
#: class names that are known and no vehicle: dropped (persons, and the other classes of Pascal
#: VOC, COCO, KITTI, IDD and Cityscapes)
DROPPED_NAMES = frozenset({
    "person", "people", "pedestrian", "person sitting", "rider", "animal",
    "aeroplane", "airplane", "bird", "boat", "bottle", "cat", "chair", "cow", "diningtable", "dining table",
    "dog", "horse", "pottedplant", "potted plant", "sheep", "sofa", "couch", "tvmonitor", "tv",
    "traffic light", "traffic sign", "fire hydrant", "stop sign", "parking meter", "bench", "elephant",
    "bear", "zebra", "giraffe", "backpack", "umbrella", "handbag", "tie", "suitcase", "frisbee", "skis",
    "snowboard", "sports ball", "kite", "baseball bat", "baseball glove", "skateboard", "surfboard",
    "tennis racket", "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple", "sandwich",
    "orange", "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "bed", "toilet", "laptop", "mouse",
    "remote", "keyboard", "cell phone", "microwave", "oven", "toaster", "sink", "refrigerator", "book",
    "clock", "vase", "scissors", "teddy bear", "hair drier", "toothbrush",
})


def normal_name(name: str) -> str:
    """A class name compared case-blind, ``_`` and ``-`` as spaces: ``"Person_sitting"`` ->
    ``"person sitting"``, ``"DontCare"`` -> ``"dontcare"``."""
    return " ".join(name.replace("_", " ").replace("-", " ").lower().split())


def class_kind(name: str, where: str) -> bool | None:
    """What a class name means: True a vehicle, False an ignore region, None dropped (a known
    class that is no vehicle). DataError naming ``where`` for a name in none of the lists
    (a typo, or a class fastdet does not know: better refused than guessed)."""
    n = normal_name(name)
    if n in VEHICLE_NAMES:
        return True
    if n in IGNORE_NAMES:
        return False
    if n in DROPPED_NAMES:
        return None
    raise DataError(f"{where}: unknown class {name[:40]!r} (vehicles: car, van, truck, bus, ...; "
                    f"ignore regions: motorcycle, bicycle, dontcare, ...; dropped: person, ...)")


# ------------------------------------------------------------------------- cameras

def camera_for(camera: str | Callable[[str], str] | None, default: str, name: str) -> str:
    """The camera id of the picture ``name``: ``camera`` itself (a string), ``camera(name)`` (a
    function) or ``default`` (None)."""
    if camera is None:
        return default
    return camera if isinstance(camera, str) else camera(name)


def text_lines(text: str, source: str) -> Iterator[tuple[str, str]]:
    """``(where, line)`` of every non-blank line of a label file's ``text``, stripped;
    ``where`` is ``"SOURCE: line N"`` (1-based) for its errors."""
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line:
            yield f"{source}: line {lineno}", line


def read_clips(path: str | Path, suffix: str, subfolder: str, folder_what: str, what: str,
               read_one: Callable[[Path], list[AnnotatedPicture]]) -> list[AnnotatedPicture]:
    """The pictures of one clip's file (``path`` a file: ``read_one(path)``) or of every
    ``*SUFFIX`` file of a folder (``ROOT`` with ``SUBFOLDER/``, or that folder itself), clips in
    name order; DataError when it is no folder (``folder_what`` names it) or has none of them
    (``what`` names the kind of file)."""
    path = Path(path)
    if path.is_file():
        return read_one(path)
    folder = check_folder(path, folder_what)
    if (folder / subfolder).is_dir():
        folder = folder / subfolder
    files = sorted(folder.glob("*" + suffix))
    if not files:
        raise DataError(f"{folder}: no *{suffix} {what} files")
    out: list[AnnotatedPicture] = []
    for f in files:
        out.extend(read_one(f))
    return out

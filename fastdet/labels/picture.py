"""The one annotated-picture type that every label reader returns and that training and
evaluation read: :class:`AnnotatedPicture`.

A picture is a file on disk (a still image) or a frame of a video; its pixels are read only
when asked (:meth:`AnnotatedPicture.load`), so a set of thousands of pictures costs their boxes
only. Boxes are ``x1, y1, x2, y2`` float64 in the picture's own pixels.

- ``targets`` ``(N, 4)``: vehicles a detector must find;
- ``ignores`` ``(M, 4)``: regions where a detection is neither a hit nor a false alarm (a vehicle
  too small, a motorcycle or bicycle, a format's own "don't care");
- ``complete``: every vehicle in the picture is labelled. Only then may negatives be cut from it
  and false alarms be counted on it; a set whose labels are partial (only some cars boxed,
  some vehicle kinds never) is *positives only* and has ``complete=False``.
- ``camera``: which camera took it (``"dawn_fog/foggy-001"``, ``"idd_mini/frontFar"``,
  ``"kitti"``, ``"clip:highway_640"``): the unit of leave-camera-out scoring.
- ``labelled_by``: ``"human"`` or ``"teacher"`` (a CNN detector's output,
  :mod:`fastdet.labels.teacher`): teacher boxes train, only human boxes judge.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..io.images import read_image
from ..io.reader import read_frames_at

#: a vehicle narrower than this fraction of the picture's width is an ignore region (data README)
MIN_WIDTH_FRACTION = 1 / 32
#: ... and so is one narrower than this many pixels
MIN_WIDTH_PX = 24.0
#: who drew a picture's boxes (``AnnotatedPicture.labelled_by``)
LABELLERS = ("human", "teacher")


def _boxes(value: object) -> np.ndarray:
    b = np.asarray(value, dtype=np.float64)
    if b.size == 0:
        return np.zeros((0, 4), np.float64)
    return np.ascontiguousarray(b.reshape(-1, 4))


@dataclass(frozen=True, eq=False)
class AnnotatedPicture:
    """One labelled picture (see the module docstring for the fields' meaning).

    ``path`` is the image file, or the video when ``frame`` (1-based) is set; ``width`` and
    ``height`` are the picture's size in pixels; ``source`` names the set it came from
    (``"dawn_fog"``), ``name`` the picture within it (a file name relative to the set's
    image folder, or ``CLIP:FRAME``).
    """

    source: str
    camera: str
    name: str
    path: Path
    width: int
    height: int
    targets: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    ignores: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    complete: bool = True
    frame: int | None = None
    labelled_by: str = "human"

    def __post_init__(self) -> None:
        if self.labelled_by not in LABELLERS:
            raise ValueError(f"labelled_by must be one of {LABELLERS}, got {self.labelled_by!r}")
        object.__setattr__(self, "targets", _boxes(self.targets))
        object.__setattr__(self, "ignores", _boxes(self.ignores))
        object.__setattr__(self, "path", Path(self.path))

    @property
    def human(self) -> bool:
        """The labels are a person's (ground truth), not a teacher's."""
        return self.labelled_by == "human"

    @property
    def boxes(self) -> np.ndarray:
        """Every labelled box, targets then ignore regions: ``(N + M, 4)`` float64."""
        return np.concatenate([self.targets, self.ignores])

    def load(self) -> np.ndarray:
        """The picture's pixels, ``(height, width, 3) uint8`` BGR (a still through
        :func:`fastdet.io.images.read_image`, a video frame through the frame reader).
        Raises :class:`~fastdet.errors.DataError` when it does not decode or its size is not
        the labelled one."""
        return load_picture(self)


def _check_pixels(pic: AnnotatedPicture, img: np.ndarray) -> np.ndarray:
    """``img`` if it is a colour picture of ``pic``'s size; DataError naming the file otherwise."""
    if img.ndim != 3 or img.shape[2] != 3:
        raise DataError(f"{pic.path}: not a colour picture (shape {img.shape})")
    if img.shape[:2] != (pic.height, pic.width):
        raise DataError(f"{pic.path}: the picture is {img.shape[1]}x{img.shape[0]}, "
                        f"its labels are for {pic.width}x{pic.height}")
    return img


def load_picture(pic: AnnotatedPicture) -> np.ndarray:
    """``(height, width, 3) uint8`` BGR pixels of ``pic``; :class:`DataError` if they do not
    decode or are not the labelled size. (Here rather than in :mod:`.load` so that the two
    modules do not import each other; :mod:`.load` re-exports it.)"""
    if pic.frame is None:
        return _check_pixels(pic, read_image(pic.path))
    got = read_frames_at(pic.path, [pic.frame], notify=lambda _: None)
    if pic.frame not in got:
        raise DataError(f"{pic.path}: the video ends before frame {pic.frame}")
    return _check_pixels(pic, got[pic.frame])


def split_small(boxes: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """``boxes (N, 4)`` split by the data README's size rule into ``(targets, too_small)``: a
    box narrower than ``MIN_WIDTH_FRACTION`` x ``width`` or ``MIN_WIDTH_PX`` is too small."""
    boxes = _boxes(boxes)
    w = boxes[:, 2] - boxes[:, 0]
    small = w < max(MIN_WIDTH_FRACTION * width, MIN_WIDTH_PX)
    return boxes[~small], boxes[small]

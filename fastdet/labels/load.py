"""Pixels of an :class:`~fastdet.labels.picture.AnnotatedPicture`: a still image or a frame of
a video (decoded up to that frame; :func:`load_pictures` decodes a video once for many)."""
from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

from ..errors import DataError
from ..io.images import read_image
from ..io.reader import read_frames_at
from .picture import AnnotatedPicture


def _check(pic: AnnotatedPicture, img: np.ndarray) -> np.ndarray:
    if img.ndim != 3 or img.shape[2] != 3:
        raise DataError(f"{pic.path}: not a colour picture (shape {img.shape})")
    if img.shape[:2] != (pic.height, pic.width):
        raise DataError(f"{pic.path}: the picture is {img.shape[1]}x{img.shape[0]}, "
                        f"its labels are for {pic.width}x{pic.height}")
    return img


def load_picture(pic: AnnotatedPicture) -> np.ndarray:
    """``(height, width, 3) uint8`` BGR pixels of ``pic``; :class:`DataError` if they do not
    decode or are not the labelled size."""
    if pic.frame is None:
        return _check(pic, read_image(pic.path))
    got = read_frames_at(pic.path, [pic.frame], notify=lambda _: None)
    if pic.frame not in got:
        raise DataError(f"{pic.path}: the video ends before frame {pic.frame}")
    return _check(pic, got[pic.frame])


def load_pictures(pics: Sequence[AnnotatedPicture]) -> Iterator[tuple[AnnotatedPicture, np.ndarray]]:
    """``(picture, pixels)`` for every picture, in order; the frames of one video are decoded
    in one pass (consecutive pictures of the same video share it)."""
    i = 0
    while i < len(pics):
        pic = pics[i]
        if pic.frame is None:
            yield pic, load_picture(pic)
            i += 1
            continue
        j = i
        while j < len(pics) and pics[j].frame is not None and pics[j].path == pic.path:
            j += 1
        group = pics[i:j]
        got = read_frames_at(pic.path, [p.frame for p in group if p.frame is not None], notify=lambda _: None)
        for p in group:
            if p.frame not in got:
                raise DataError(f"{p.path}: the video ends before frame {p.frame}")
            yield p, _check(p, got[p.frame])
        i = j

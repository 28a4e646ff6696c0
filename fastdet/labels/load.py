"""Pixels of an :class:`~fastdet.labels.picture.AnnotatedPicture`: a still image or a frame of
a video (decoded up to that frame; :func:`load_pictures` decodes a video once for many)."""
from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np

from ..errors import DataError
from ..io.reader import read_frames_at
from .picture import AnnotatedPicture, load_picture
from .picture import _check_pixels as _check

__all__ = ["load_picture", "load_pictures"]


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

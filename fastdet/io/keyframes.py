"""Keyframe lists of sparsely annotated clips (``CLIP.frames`` beside ``CLIP.gt.txt``).

A sparsely annotated clip has ground truth on some frames only. Its keyframe file lists
them, one 1-based frame number a line (blank lines skipped). Only those frames are scored:
a listed frame without ground-truth lines has no vehicle, and a detection on a frame that is
not listed is neither a hit nor a false alarm (nobody looked there).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import DataError
from .files import read_input_text

#: largest frame number a keyframe list may hold (as box files: int32)
MAX_FRAME = 2**31 - 1
#: suffix of a ground-truth file, and of the keyframe list that goes with it
GT_SUFFIX = ".gt.txt"
KEYFRAMES_SUFFIX = ".frames"


def keyframes_path(gt_path: str | os.PathLike[str]) -> Path:
    """The keyframe list that belongs to ``gt_path``: ``CLIP.gt.txt`` -> ``CLIP.frames``
    (any other name: the same name with ``.frames`` in place of its last suffix)."""
    p = Path(gt_path)
    name = p.name
    stem = name[: -len(GT_SUFFIX)] if name.endswith(GT_SUFFIX) else p.stem
    return p.with_name(stem + KEYFRAMES_SUFFIX)


def parse_keyframes(text: str, source: str = "<string>") -> np.ndarray:
    """The frame numbers of a keyframe list: ``(K,) int64``, sorted, each >= 1, no repeats.

    A line that is not a whole number in 1..:data:`MAX_FRAME`, a frame listed twice, or a list without any
    frame raises :class:`~fastdet.errors.DataError` naming the source and the line.
    """
    frames: list[int] = []
    seen: dict[int, int] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        try:
            f = int(line)
        except ValueError:
            raise DataError(f"{source}: line {lineno}: expected a frame number, got {line[:40]!r}") from None
        if f < 1:
            raise DataError(f"{source}: line {lineno}: frame must be >= 1 (frames are 1-based), got {f}")
        if f > MAX_FRAME:
            raise DataError(f"{source}: line {lineno}: frame {line[:40]} is out of range (at most {MAX_FRAME})")
        if f in seen:
            raise DataError(f"{source}: line {lineno}: frame {f} is listed twice (first on line {seen[f]})")
        seen[f] = lineno
        frames.append(f)
    if not frames:
        raise DataError(f"{source}: no frame numbers")
    return np.array(sorted(frames), np.int64)


def read_keyframes(path: str | os.PathLike[str]) -> np.ndarray:
    """:func:`parse_keyframes` of a file (missing or unreadable file: DataError)."""
    name = os.fspath(path)
    if os.path.isdir(name):
        raise DataError(f"{name}: is a directory, expected a keyframe list")
    return parse_keyframes(read_input_text(name, "keyframe list"), name)


def keyframes_for(gt_path: str | os.PathLike[str]) -> np.ndarray | None:
    """The keyframes of the clip whose ground truth is ``gt_path`` when its keyframe list
    (:func:`keyframes_path`) exists, else None (a densely annotated clip)."""
    p = keyframes_path(gt_path)
    return read_keyframes(p) if p.exists() else None

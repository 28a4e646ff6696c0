"""Annotated clips: MOTChallenge ground truth (``CLIP.gt.txt``, read by
:func:`fastdet.io.motfiles.parse_gt`) as one :class:`~fastdet.labels.picture.AnnotatedPicture`
per annotated frame, ``frame`` set and ``path`` the video.

Layout (the shared data)::

    ROOT/annotations/CLIP.gt.txt     frame,id,left,top,width,height,consider,class,visibility
    ROOT/annotations/CLIP.frames     (keyframe clips only) the annotated frames, one a line
    ROOT/videos/CLIP.mp4             (any video suffix: .mp4 .avi .mov .mkv ...)

``PATH`` is ``ROOT`` (every clip in ``annotations/``) or one ``CLIP.gt.txt`` (its video is
``../videos/CLIP.*``, or ``CLIP.*`` beside it).

Which frames: a *keyframe clip* (with ``CLIP.frames``, :mod:`fastdet.io.keyframes`) gives
exactly its listed frames (a listed frame without lines has no vehicle); a ground-truth line
on a frame that is not listed is a :class:`~fastdet.errors.DataError` (nobody looked there).
A *densely annotated clip* (no ``.frames``) gives every ``every``-th frame from frame 1
(1, 6, 11, ... for ``every=5``) up to the last frame with ground truth: neighbouring frames
are nearly the same picture, and the boxes between keyframes are interpolated.

``consider`` = 1 lines are vehicles, ``consider`` = 0 lines ignore regions; then the rules of
:mod:`fastdet.labels.rules` (size rule, clipping, boxes outside the picture: errors name the
line). The picture's size is the video's (from its container, no frame decoded).
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..io.keyframes import GT_SUFFIX, keyframes_for
from ..io.motfiles import parse_gt
from .imagesize import video_size
from .picture import AnnotatedPicture
from .rules import Box, camera_for, make_picture, not_empty, read_clips, read_text

#: video file suffixes looked for beside a clip's labels (lower case)
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv")
#: a densely annotated clip gives every this-many-th frame by default
EVERY = 5


def find_video(label: Path, clip: str) -> Path:
    """The video of ``clip`` whose labels are the file ``label``: ``videos/CLIP.*`` beside the
    labels' folder (the shared layout), or ``CLIP.*`` beside the file; DataError naming
    ``label`` when there is none."""
    for folder in (label.parent.parent / "videos", label.parent):
        for suffix in VIDEO_SUFFIXES:
            for p in (folder / (clip + suffix), folder / (clip + suffix.upper())):
                if p.is_file():
                    return p
    raise DataError(f"{label}: no video {label.parent.parent / 'videos' / clip}.* for these labels")


def clip_name(path: Path, suffix: str) -> str:
    """``CLIP`` of ``.../CLIP<suffix>``."""
    return path.name[: -len(suffix)] if path.name.endswith(suffix) else path.stem


def _line_numbers(text: str) -> list[int]:
    """The line number of each box row of a MOT file (blank lines are skipped, as the parser does)."""
    return [n for n, line in enumerate(text.splitlines(), start=1) if line.strip()]


def read_mot_clip(gt_path: str | Path, *, every: int = EVERY, source: str | None = None,
                  camera: str | Callable[[str], str] | None = None, complete: bool = True,
                  video: str | Path | None = None) -> list[AnnotatedPicture]:
    """The annotated frames of one clip (``CLIP.gt.txt``; see the module docstring) in frame
    order. source: the set's name (default ``CLIP``); camera: default ``clip:CLIP``; the
    picture's name is ``CLIP:FRAME``; video: the clip's video when it is not found by
    :func:`find_video`. Raises DataError on the first error."""
    if every < 1:
        raise DataError(f"every must be >= 1 (every how many frames of a dense clip), got {every}")
    gt_path = Path(gt_path)
    clip = clip_name(gt_path, GT_SUFFIX)
    source = source or clip
    text = read_text(gt_path, "ground-truth file")
    gt = parse_gt(text, str(gt_path))
    lines = _line_numbers(text)
    keyframes = keyframes_for(gt_path)
    frames_of = gt.frames if gt.frames is not None else np.zeros(0, np.int64)
    if keyframes is not None:
        unlisted = np.flatnonzero(~np.isin(frames_of, keyframes))
        if unlisted.size:
            k = int(unlisted[0])
            raise DataError(f"{gt_path}: line {lines[k]}: frame {int(frames_of[k])} is not a keyframe of "
                            f"{gt_path.name[: -len(GT_SUFFIX)]}.frames (only listed frames are annotated)")
        frames = [int(f) for f in keyframes]
    else:
        last = int(frames_of.max()) if len(frames_of) else 0
        frames = list(range(1, last + 1, every))
    path = Path(video) if video is not None else find_video(gt_path, clip)
    width, height = video_size(path)
    consider = gt.consider if gt.consider is not None else np.ones(len(gt), bool)
    by_frame: dict[int, list[Box]] = {f: [] for f in frames}
    for k in range(len(gt)):
        f = int(frames_of[k])
        if f in by_frame:
            x1, y1, x2, y2 = (float(v) for v in gt.boxes[k])
            by_frame[f].append(Box(x1, y1, x2, y2, bool(consider[k]), f"{gt_path}: line {lines[k]}"))
    pictures = []
    for f in frames:
        name = f"{clip}:{f}"
        pictures.append(make_picture(source=source, camera=camera_for(camera, f"clip:{clip}", name), name=name,
                                     path=path, width=width, height=height, boxes=by_frame[f], complete=complete,
                                     frame=f))
    return not_empty(pictures, gt_path, "annotated frames")


def read_mot(path: str | Path, *, every: int = EVERY, source: str | None = None,
             camera: str | Callable[[str], str] | None = None, complete: bool = True) -> list[AnnotatedPicture]:
    """The annotated frames of one clip (``path`` a ``CLIP.gt.txt``) or of every clip of a
    folder (``ROOT`` with ``annotations/*.gt.txt``, or the annotations folder itself), clips
    in name order; see :func:`read_mot_clip`."""
    return read_clips(path, GT_SUFFIX, "annotations", "MOTChallenge clips", "ground-truth",
                      lambda f: read_mot_clip(f, every=every, source=source, camera=camera, complete=complete))

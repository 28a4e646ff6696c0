"""Teacher labels: what a CNN detector saw on the frames of a clip, as training labels (not
ground truth: never score a detector against them as accuracy).

Layout (the shared data)::

    ROOT/teacher/CLIP.teacher.txt    frame,-1,left,top,width,height,score,class,-1,-1
    ROOT/teacher/CLIP.frames         the frames the teacher looked at, one a line
    ROOT/videos/CLIP.mp4             (any video suffix: the shared ``ebuarip_640`` is an .avi)

``PATH`` is ``ROOT`` (every clip in ``teacher/``), the ``teacher/`` folder, or one
``CLIP.teacher.txt``. ``class`` is a COCO-80 class index (0-based, as Ultralytics and YOLOX
number them): 2 car, 5 bus, 7 truck are vehicles; 1 bicycle, 3 motorcycle are two-wheelers;
any other index below 80 is dropped (a person, a traffic light); 80 and above is refused.

One :class:`~fastdet.labels.picture.AnnotatedPicture` per listed frame (a listed frame without
lines: the teacher saw nothing there), ``labelled_by="teacher"``, ``complete=True`` (the
teacher looked at the whole frame):

- a vehicle with ``score >= min_score`` (default 0.3: the teacher's F1 is 0.96 there on the
  annotated clips) is a target;
- a vehicle with a lower score (down to the file's floor: whatever the file holds) and every
  two-wheeler is an ignore region: the teacher is unsure there, so that place is neither a
  positive nor a negative;
- then the rules of :mod:`fastdet.labels.rules` (size rule, clipping, boxes outside the picture).

A line that is not 8 to 10 numbers, a fractional or out-of-range frame, a score outside
0..1, an unknown class, or a frame that is not in ``CLIP.frames`` raises a
:class:`~fastdet.errors.DataError` naming the file and the line.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..errors import DataError
from ..io.keyframes import read_keyframes
from .imagesize import video_size
from .mot import clip_name, find_video
from .picture import AnnotatedPicture
from .rules import Box, camera_for, make_picture, not_empty, number, read_clips, read_text, text_lines

#: suffix of a teacher detection file and of its list of frames looked at
TEACHER_SUFFIX = ".teacher.txt"
FRAMES_SUFFIX = ".frames"
#: a teacher vehicle at least this sure is a target (below: an ignore region)
MIN_SCORE = 0.3
#: COCO-80 class indices: vehicles and two-wheelers (everything else below 80 is dropped)
COCO_VEHICLES = {2: "car", 5: "bus", 7: "truck"}
COCO_TWO_WHEELERS = {1: "bicycle", 3: "motorcycle"}
COCO_CLASSES = 80


def parse_teacher(text: str, source: str, min_score: float = MIN_SCORE) -> dict[int, list[Box]]:
    """``{frame: boxes}`` of a teacher file's ``text`` (frames with boxes only; dropped classes
    left out); ``source`` names the file in errors."""
    out: dict[int, list[Box]] = {}
    for where, line in text_lines(text, source):
        fields = [f.strip() for f in line.split(",")]
        if not 8 <= len(fields) <= 10:
            raise DataError(f"{where}: expected 10 comma-separated fields "
                            f"'frame,-1,left,top,width,height,score,class,-1,-1', got {len(fields)}: {line[:60]!r}")
        names = ("frame", "id", "left", "top", "width", "height", "score", "class", "x", "y")
        v = [number(f, n, where) for f, n in zip(fields, names)]
        frame, left, top, w, h, score, cls = v[0], v[2], v[3], v[4], v[5], v[6], v[7]
        if frame != int(frame) or not 1 <= frame < 2**31:
            raise DataError(f"{where}: frame must be a whole number >= 1 (frames are 1-based), got {fields[0]!r}")
        if not 0.0 <= score <= 1.0:
            raise DataError(f"{where}: score must be 0 to 1, got {fields[6]!r}")
        if cls != int(cls) or not 0 <= cls < COCO_CLASSES:
            raise DataError(f"{where}: unknown class {fields[7]!r} (COCO-80 class indices 0 to 79: 2 car, "
                            f"3 motorcycle, 5 bus, 7 truck)")
        if w < 0 or h < 0:
            raise DataError(f"{where}: negative box size width={fields[4]} height={fields[5]}")
        c = int(cls)
        if c in COCO_VEHICLES:
            vehicle = score >= min_score
        elif c in COCO_TWO_WHEELERS:
            vehicle = False
        else:
            continue
        out.setdefault(int(frame), []).append(Box(left, top, left + w, top + h, vehicle, where))
    return out


def read_teacher_clip(path: str | Path, *, min_score: float = MIN_SCORE, source: str | None = None,
                      camera: str | Callable[[str], str] | None = None, complete: bool = True,
                      video: str | Path | None = None) -> list[AnnotatedPicture]:
    """The frames a teacher looked at in one clip (``CLIP.teacher.txt`` and ``CLIP.frames``
    beside it; see the module docstring), in frame order, ``labelled_by="teacher"``. source:
    the set's name (default ``teacher:CLIP``); camera: default ``teacher:CLIP``; the picture's
    name is ``CLIP:FRAME``; complete: False to use the frames as positives only; video: the
    clip's video when it is not found by :func:`~fastdet.labels.mot.find_video`."""
    if not 0.0 <= min_score <= 1.0:
        raise DataError(f"min-score must be 0 to 1, got {min_score:g}")
    path = Path(path)
    clip = clip_name(path, TEACHER_SUFFIX)
    source = source or f"teacher:{clip}"
    frames_path = path.with_name(clip + FRAMES_SUFFIX)
    boxes = parse_teacher(read_text(path, "teacher file"), str(path), min_score)
    frames = [int(f) for f in read_keyframes(frames_path)]
    listed = set(frames)
    for f, bs in boxes.items():
        if f not in listed:
            raise DataError(f"{bs[0].where}: frame {f} is not in {frames_path.name} (the frames the teacher "
                            f"looked at)")
    vid = Path(video) if video is not None else find_video(path, clip)
    width, height = video_size(vid)
    pictures = []
    for f in frames:
        name = f"{clip}:{f}"
        pictures.append(make_picture(source=source, camera=camera_for(camera, f"teacher:{clip}", name),
                                     name=name, path=vid, width=width, height=height, boxes=boxes.get(f, []),
                                     complete=complete, frame=f, labelled_by="teacher"))
    return not_empty(pictures, path, "frames")


def read_teacher(path: str | Path, *, min_score: float = MIN_SCORE, source: str | None = None,
                 camera: str | Callable[[str], str] | None = None, complete: bool = True) -> list[AnnotatedPicture]:
    """The teacher's frames of one clip (``path`` a ``CLIP.teacher.txt``) or of every clip of
    a folder (``ROOT`` with ``teacher/``, or the ``teacher/`` folder itself), clips in name
    order; see :func:`read_teacher_clip`."""
    return read_clips(path, TEACHER_SUFFIX, "teacher", "teacher", "teacher",
                      lambda f: read_teacher_clip(f, min_score=min_score, source=source, camera=camera,
                                                  complete=complete))

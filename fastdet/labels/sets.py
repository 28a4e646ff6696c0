"""Labelled sets by name: a ``--frames SPEC`` of the command line (:func:`parse_spec`,
:func:`read_spec`) and every labelled source of the shared data (:func:`shared_sets`).

A spec is ``FORMAT:PATH[,OPTION...]``::

    yolo:../shared/data/frames/idd_mini,positives-only,camera=idd
    voc:my_set                      (my_set/voc/*.xml + my_set/images/)
    coco:my_set/instances.json
    kitti:my_kitti
    mot:../shared/data              (every clip in annotations/; or one CLIP.gt.txt)
    teacher:../shared/data,min-score=0.5

FORMAT is one of :data:`FORMATS`; PATH (no commas) is the set's root folder laid out as the
shared data is (or the json / gt / teacher file); the options:

- ``positives-only``: ``complete=False`` (not every vehicle is labelled: no negatives are cut
  from the pictures, no false alarm counted on them);
- ``camera=NAME``: one camera id for the whole set (default: the reader's: the set's folder
  name for stills, ``clip:CLIP`` / ``teacher:CLIP`` per clip);
- ``min-score=F`` (teacher only): a teacher vehicle at least this sure is a target (default 0.3);
- ``every=N`` (mot only): every N-th frame of a densely annotated clip (default 5).

A spec that does not parse is one :class:`~fastdet.errors.DataError` line.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import DataError
from .coco import read_coco
from .kitti import read_kitti
from .mot import EVERY, read_mot, read_mot_clip
from .picture import AnnotatedPicture
from .rules import check_folder
from .teacher import MIN_SCORE, TEACHER_SUFFIX, read_teacher
from .voc import read_voc
from .yolo import read_yolo

#: the formats a spec may name
FORMATS = ("yolo", "voc", "coco", "kitti", "mot", "teacher")


@dataclass(frozen=True)
class FrameSpec:
    """A parsed ``--frames`` spec (see the module docstring): ``format``, ``path``,
    ``complete`` (False: ``positives-only``), ``camera`` (None: the reader's default),
    ``min_score`` (teacher), ``every`` (mot)."""

    format: str
    path: Path
    complete: bool = True
    camera: str | None = None
    min_score: float = MIN_SCORE
    every: int = EVERY

    def read(self) -> list[AnnotatedPicture]:
        """The set's pictures (DataError on the first error of the whole set)."""
        cam, complete = self.camera, self.complete
        if self.format == "yolo":
            return read_yolo(self.path, camera=cam, complete=complete)
        if self.format == "voc":
            return read_voc(self.path, camera=cam, complete=complete)
        if self.format == "coco":
            return read_coco(self.path, camera=cam, complete=complete)
        if self.format == "kitti":
            return read_kitti(self.path, camera=cam, complete=complete)
        if self.format == "mot":
            return read_mot(self.path, every=self.every, camera=cam, complete=complete)
        return read_teacher(self.path, min_score=self.min_score, camera=cam, complete=complete)


def _float(spec: str, key: str, value: str) -> float:
    try:
        return float(value)
    except ValueError:
        raise DataError(f"--frames {spec}: {key} must be a number, got {value!r}") from None


def parse_spec(spec: str) -> FrameSpec:
    """The :class:`FrameSpec` of ``"FORMAT:PATH[,OPTION...]"`` (nothing is read yet; the path
    need not exist). DataError (one line quoting the spec) for an unknown format or option, an
    empty path, or an option value that does not parse."""
    fmt, colon, rest = spec.partition(":")
    fmt = fmt.strip().lower()
    if not colon or fmt not in FORMATS:
        raise DataError(f"--frames {spec}: expected FORMAT:PATH[,OPTION...] with FORMAT one of "
                        f"{', '.join(FORMATS)}")
    path, *options = rest.split(",")
    if not path.strip():
        raise DataError(f"--frames {spec}: no PATH after '{fmt}:'")
    kw: dict[str, object] = {}
    for opt in options:
        key, eq, value = (s.strip() for s in opt.partition("="))
        if key == "positives-only" and not eq:
            kw["complete"] = False
        elif key == "camera" and value:
            kw["camera"] = value
        elif key == "min-score" and value and fmt == "teacher":
            score = _float(spec, key, value)
            if not 0.0 <= score <= 1.0:
                raise DataError(f"--frames {spec}: min-score must be 0 to 1, got {value}")
            kw["min_score"] = score
        elif key == "every" and value and fmt == "mot":
            n = _float(spec, key, value)
            if n != int(n) or n < 1:
                raise DataError(f"--frames {spec}: every must be a whole number >= 1, got {value}")
            kw["every"] = int(n)
        else:
            extra = {"teacher": ", min-score=F", "mot": ", every=N"}.get(fmt, "")
            raise DataError(f"--frames {spec}: unknown option {opt.strip()!r} for {fmt} "
                            f"(options: positives-only, camera=NAME{extra})")
    return FrameSpec(fmt, Path(path.strip()), **kw)  # type: ignore[arg-type]


def read_spec(spec: str) -> list[AnnotatedPicture]:
    """The pictures of the set ``spec`` names (:func:`parse_spec`, then :meth:`FrameSpec.read`)."""
    return parse_spec(spec).read()


# ------------------------------------------------------------------------- the shared data

#: the annotated clips (``annotations/``) that share one camera, and its id
UDACITY_CLIPS = ("test_video", "test_small1")
UDACITY_CAMERA = "udacity"
#: the camera of ``frames/kitti_tiny``: the car-roof camera the ``vehicles/KITTI_extracted`` crops come from
KITTI_CAMERA = "kitti"


def _own_camera(source: str) -> Callable[[str], str]:
    """Every picture its own camera: ``SOURCE/STEM`` (pictures collected from the web)."""
    return lambda name: f"{source}/{Path(name).stem}"


def _idd_camera(name: str) -> str:
    """``train/frontFar/SEQ/x.jpg`` -> ``idd_mini/frontFar``: the IDD rig's camera folder."""
    parts = name.split("/")
    return f"idd_mini/{parts[1] if len(parts) > 2 else parts[0]}"


def shared_sets(data_dir: str | Path) -> dict[str, list[AnnotatedPicture]]:
    """Every labelled source of the shared data folder ``data_dir`` (its README), by set name,
    human-labelled sets first:

    - ``dawn_fog`` (Pascal VOC): complete; every picture its own camera, ``dawn_fog/STEM``
      (collected from the web);
    - ``dawn_weather`` (COCO): **partial** labels (about two salient cars a picture, trucks
      and buses never): ``complete=False``; every picture its own camera, ``dawn_weather/STEM``;
    - ``idd_mini`` (YOLO): positives only (autorickshaws, motorcycles, tractors, trailers are
      not labelled): ``complete=False``; camera ``idd_mini/CAMERA`` (the rig's camera folder:
      frontFar, frontNear, sideLeft, sideRight, rearNear, highquality_16k);
    - ``kitti_tiny`` (KITTI): complete; camera ``kitti`` -- the same camera as the
      ``vehicles/KITTI_extracted`` training crops, so a leave-camera-out split must keep the
      two on one side;
    - the five annotated clips ``test_video``, ``test_small1``, ``highway_640``,
      ``boston_street``, ``motorcycle_highway`` (MOTChallenge; every 5th frame of the dense
      two, the keyframes of the others): complete; camera ``clip:CLIP``, except the two
      Udacity clips, one camera ``udacity``;
    - the 17 teacher clips as ``teacher:CLIP`` (``labelled_by="teacher"``): complete;
      camera ``teacher:CLIP``. Teacher boxes are for training, never for scoring.

    Every picture says who labelled it (``labelled_by``, ``human``); :func:`human_sets` and
    :func:`teacher_sets` pick either kind. A source whose folder is missing is left out;
    DataError on the first error anywhere else."""
    d = check_folder(Path(data_dir), "data")
    frames = d / "frames"
    readers = {
        "dawn_fog": lambda f: read_voc(f, camera=_own_camera("dawn_fog")),
        "dawn_weather": lambda f: read_coco(f, camera=_own_camera("dawn_weather"), complete=False),
        "idd_mini": lambda f: read_yolo(f, camera=_idd_camera, complete=False),
        "kitti_tiny": lambda f: read_kitti(f, camera=KITTI_CAMERA),
    }
    # a data folder may hold only some sources (a clips-only folder): a set whose folder is
    # missing is left out; one that is there must read whole
    sets: dict[str, list[AnnotatedPicture]] = {
        name: read(frames / name) for name, read in readers.items() if (frames / name).is_dir()}
    for gt in sorted((d / "annotations").glob("*.gt.txt")):
        clip = gt.name.removesuffix(".gt.txt")
        sets[clip] = read_mot_clip(gt, camera=UDACITY_CAMERA if clip in UDACITY_CLIPS else None)
    for f in sorted((d / "teacher").glob("*" + TEACHER_SUFFIX)):
        pics = read_teacher(f)
        sets[pics[0].source] = pics
    return sets


def human_sets(sets: dict[str, list[AnnotatedPicture]]) -> dict[str, list[AnnotatedPicture]]:
    """The sets of ``sets`` whose pictures people labelled (ground truth: for scoring)."""
    return {k: v for k, v in sets.items() if v and all(p.human for p in v)}


def teacher_sets(sets: dict[str, list[AnnotatedPicture]]) -> dict[str, list[AnnotatedPicture]]:
    """The sets of ``sets`` whose pictures a teacher labelled (for training only)."""
    return {k: v for k, v in sets.items() if v and not any(p.human for p in v)}

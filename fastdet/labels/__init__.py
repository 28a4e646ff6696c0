"""Labelled pictures from any common format, as one type: :class:`AnnotatedPicture`.

Readers (one module a format) turn YOLO txt, Pascal VOC xml, COCO json, KITTI label_2,
MOTChallenge clips and teacher detection files into lists of pictures with target boxes,
ignore regions and whether their labels are complete; training and evaluation read only this.
:func:`read_spec` reads the set a ``--frames FORMAT:PATH[,options]`` names, :func:`shared_sets`
every labelled source of the shared data. The rules and the camera ids: ``docs/labels.md``.
"""
from __future__ import annotations

from .coco import read_coco
from .kitti import read_kitti
from .load import load_pictures
from .mot import read_mot
from .picture import LABELLERS, MIN_WIDTH_FRACTION, MIN_WIDTH_PX, AnnotatedPicture, load_picture, split_small
from .sets import FORMATS, FrameSpec, human_sets, parse_spec, read_spec, shared_sets, teacher_sets
from .teacher import read_teacher
from .voc import read_voc
from .yolo import read_yolo

__all__ = [
    "AnnotatedPicture", "split_small", "MIN_WIDTH_FRACTION", "MIN_WIDTH_PX", "LABELLERS",
    "load_picture", "load_pictures",
    "read_yolo", "read_voc", "read_coco", "read_kitti", "read_mot", "read_teacher",
    "FORMATS", "FrameSpec", "parse_spec", "read_spec", "shared_sets", "human_sets", "teacher_sets",
]

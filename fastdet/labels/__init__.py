"""Labelled pictures from any common format, as one type: :class:`AnnotatedPicture`.

Readers (one module a format) turn YOLO txt, Pascal VOC xml, COCO json, KITTI label_2,
MOTChallenge clips and teacher detection files into lists of pictures with target boxes,
ignore regions and whether their labels are complete; training and evaluation read only this.
"""
from __future__ import annotations

from .picture import MIN_WIDTH_FRACTION, MIN_WIDTH_PX, AnnotatedPicture, split_small

__all__ = ["AnnotatedPicture", "split_small", "MIN_WIDTH_FRACTION", "MIN_WIDTH_PX"]

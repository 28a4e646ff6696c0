"""How a teacher CNN labels frames (:class:`TeacherConfig`): the settings of
:class:`fastdet.teacher.TeacherDetector` and ``python -m fastdet label``."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ._base import Config

#: COCO class ids of vehicles: 2 car, 3 motorcycle, 5 bus, 7 truck
COCO_VEHICLES: tuple[int, ...] = (2, 3, 5, 7)
#: the input width used when neither the model nor the caller fixes one (px)
DEFAULT_TEACHER_SIZE = 640
#: bounds of the input width (px): below 32 there is no grid cell of stride 32; above
#: 4096 one input takes gigabytes of activations
MIN_TEACHER_SIZE, MAX_TEACHER_SIZE = 32, 4096


@dataclass(frozen=True)
class TeacherConfig(Config):
    """Settings of a YOLOX-style teacher detector (:mod:`fastdet.teacher.yolox`).

    size: the network input's width in px, rounded to the nearest multiple of 32 (at least
        32); its height follows each frame's aspect ratio, rounded up to a multiple of 32
        (a 1280x720 frame at 640: a 640x384 input). ``None``: :data:`DEFAULT_TEACHER_SIZE`
        for a model with a free input size, the model's own size for a fixed one.
    min_score: boxes scoring below this (objectness x class probability, in [0, 1]) are
        dropped; 0.1 is the floor of the shared teacher files (``teacher/*.teacher.txt``).
    nms_iou: within one class, a box overlapping a higher-scoring one by more than this
        (intersection over union) is dropped.
    classes: the COCO class ids kept (default the vehicles, :data:`COCO_VEHICLES`).
    threads: onnxruntime's intra-op threads; ``None``: ``NUMBA_NUM_THREADS`` when set, else
        the cores this process may run on.
    """

    size: int | None = None
    min_score: float = 0.1
    nms_iou: float = 0.45
    classes: tuple[int, ...] = COCO_VEHICLES
    threads: int | None = None

    def __post_init__(self) -> None:
        if self.size is not None and (isinstance(self.size, bool) or int(self.size) != self.size
                                      or not MIN_TEACHER_SIZE <= self.size <= MAX_TEACHER_SIZE):
            raise ValueError(f"size must be a whole number of px from {MIN_TEACHER_SIZE} to {MAX_TEACHER_SIZE}, "
                             f"got {self.size!r}")
        if not (isinstance(self.min_score, (int, float)) and math.isfinite(self.min_score)
                and 0 < self.min_score <= 1):
            raise ValueError(f"min_score must be in (0, 1], got {self.min_score!r}")
        if not (isinstance(self.nms_iou, (int, float)) and math.isfinite(self.nms_iou) and 0 < self.nms_iou <= 1):
            raise ValueError(f"nms_iou must be in (0, 1], got {self.nms_iou!r}")
        if not self.classes or any(isinstance(c, bool) or int(c) != c or not 0 <= c < 80 for c in self.classes):
            raise ValueError(f"classes must be COCO class ids from 0 to 79, got {self.classes!r}")
        if len(set(self.classes)) != len(self.classes):
            raise ValueError(f"classes must not repeat, got {self.classes!r}")
        if self.threads is not None and (isinstance(self.threads, bool) or int(self.threads) != self.threads
                                         or self.threads < 1):
            raise ValueError(f"threads must be a whole number >= 1, got {self.threads!r}")

    def input_width(self, model_width: int | None = None) -> int:
        """The network input's width in px: ``model_width`` when the model fixes it, else
        :attr:`size` (default :data:`DEFAULT_TEACHER_SIZE`) rounded to a multiple of 32."""
        if model_width is not None:
            return model_width
        size = DEFAULT_TEACHER_SIZE if self.size is None else self.size
        return max(32, 32 * int(size / 32 + 0.5))  # halves up

"""One box per vehicle from each frame's positive windows by non-maximum suppression
(:class:`NmsStage`; ``PipelineConfig(boxes='nms')``), in the heat map's place.

The heat map sums the windows of recent frames and boxes each blob: it asks a vehicle for
several frames of evidence and gives a weak window classifier's scattered windows one box.
A model fitted to one camera (``fastdet adapt``) has windows that sit on the vehicles, and
there the blobs lose them: neighbours side by side merge into one blob, and a blob's outline
is not its vehicle's box. So the windows themselves are the boxes: the positive windows of the
main model and of the camera's side-view component (:attr:`fastdet.model.Model.side`) in the
frame, greedily by score, a window dropped when it overlaps one already kept by IoU above
:data:`NMS_IOU` (the picture search's rule, :class:`~fastdet.config.PictureSearch`) or when
more than :data:`NMS_INSIDE` of its area lies inside one (the rule of DPM's ``nms.m``,
Felzenszwalb et al.: windows of several sizes on one vehicle, a small one inside a large one,
have a small IoU).
The tracker, the box regressor and the second-box rule (:mod:`fastdet.video.plausible`) then
run as on the heat map's boxes; the tracker splits no box (a window holds one vehicle).
Which of the two a camera gets is chosen by ``fastdet adapt`` on frames it kept aside and
recorded in its model file; what each scored: docs/training.md.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..detections import Detections
from .plausible import duplicates
from .state import FrameState, Stage

#: two windows overlapping at more than this IoU see the same vehicle (the picture search's
#: ``PictureSearch.nms_iou``)
NMS_IOU = 0.3
#: a window with more than this fraction of its area inside a higher-scored one sees its vehicle
#: (DPM's ``nms.m`` overlap, the intersection over the lower-scored box's area)
NMS_INSIDE = 0.5


def nms_boxes(windows: Detections, max_iou: float = NMS_IOU, max_inside: float = NMS_INSIDE) -> Detections:
    """One box per vehicle of ``windows`` (a frame's positive windows; those of the main model and
    its components -- a camera's side-view one --, not the oncoming model's, when they have a
    ``part`` column): the windows kept by greedy suppression at ``max_iou`` and
    ``max_inside`` (:func:`~fastdet.video.plausible.duplicates`), boxes ``(N, 4) int32`` and the
    windows' scores ``(N,) float32``, in the windows' order."""
    w = windows[~windows.is_oncoming] if windows.part is not None else windows
    if len(w) == 0:
        return Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32))
    keep = duplicates(w.boxes, w.scores, max_iou, max_inside)
    return Detections(w.boxes[keep].astype(np.int32), w.scores[keep].astype(np.float32))


class NmsStage(Stage):
    """The boxes of a frame: the positive windows of the main model (and its side-view component)
    after non-maximum suppression
    (:func:`nms_boxes`), in the heat map's place (module docstring). No heat map: nothing of
    one frame is carried to the next. A frame of another size calls ``on_new_size(first)``
    as :class:`~fastdet.video.box_stages.HeatStage` does (``first``: the first frame)."""

    name = "nms"

    def __init__(self, on_new_size: Callable[[bool], None]) -> None:
        self.on_new_size = on_new_size
        self.shape: tuple[int, int] | None = None

    def __call__(self, s: FrameState) -> FrameState:
        if s.shape != self.shape:
            self.on_new_size(self.shape is None)
            self.shape = s.shape
        s.boxes = s.out = nms_boxes(s.windows)
        return s

"""The tracker that gives every vehicle box an id (:class:`TrackerConfig`)."""
from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal

from ._base import Config


@dataclass(frozen=True)
class TrackerConfig(Config):
    """The tracker that gives every vehicle box an id (:mod:`fastdet.video.track`): ByteTrack
    (Zhang et al., ECCV 2022) on the heat map's boxes.

    High-confidence boxes are the heat map's boxes (blob peak above the heat threshold);
    low-confidence boxes are the weak blobs whose peak heat is above ``low_heat`` x the
    threshold but not above it (:meth:`fastdet.video.heatmap.HeatMap.weak_boxes`).

    low_heat: fraction of each heat map's threshold a weak blob's peak must exceed to be a
        low-confidence box; ``0`` = no low-confidence boxes.
    match_iou: IoU a high-confidence box needs with a track's predicted box to continue it
        (first association; ByteTrack's ``match_thresh`` 0.8 is a cost ``1 - IoU``, i.e. 0.2).
    low_match_iou: IoU a low-confidence box needs with a track that the first association
        left unmatched (second association; ByteTrack: 0.5).
    tentative_match_iou: IoU a high-confidence box needs to continue a tentative track
        (ByteTrack: 0.3).
    min_hits: frames a track must be matched in a row before it is confirmed and gets its
        id; a tentative track that misses a frame is dropped. 1 = confirmed at once (the
        heat map already asks a vehicle for several frames of evidence).
    max_lost: frames a confirmed track that found no box is kept (predicted) before it is
        dropped; ByteTrack's ``track_buffer``.
    split_overlap: a high-confidence box that holds at least this fraction of the predicted
        boxes of two or more tracks (merged blobs of vehicles side by side) is split between
        them (:func:`fastdet.video.track.split_merged`); ``0`` = never split.
    output: which box a tracked vehicle is reported with: ``'detection'`` (the heat map's box
        of this frame) or ``'filtered'`` (the Kalman filter's estimate).
    buffer: boxes are grown by this fraction of their width / height on every side before
        the IoU of an association (the buffered IoU of C-BIoU, Yang et al., WACV 2023, whose
        first stage uses 0.3): an oncoming car 45 px wide moves 15-20 px a frame at 25 fps,
        so its new box barely overlaps its predicted one until the filter has learnt its
        velocity. 0 = plain IoU.
    std_position, std_velocity, init_velocity: Kalman noise, fractions of the box's width /
        height per frame (:class:`fastdet.video.kalman.BoxKalman`). ``std_position`` and
        ``std_velocity`` are ByteTrack's; ``init_velocity``, the uncertainty of a new track's
        velocity, is 4x ByteTrack's 10/160 (made for pedestrians at 30 fps): vehicles cross the
        view at up to half their width per frame, and with 0.25 a track knows its velocity from
        its second box.
    hold_row: a lost track is predicted at its last row: its vertical velocity is set to 0,
        as its size velocities are. On a road, a vehicle's row in the picture moves with its
        distance, and so with its size, which a lost track keeps; and the vertical velocity
        learnt from a few boxes is mostly their noise (heat-map boxes whose top and bottom
        jump by a quarter of their height from frame to frame), which, extrapolated over the
        frames a vehicle is missed, moves the prediction off the vehicle and the vehicle gets
        a new id when it is found again. The horizontal velocity (vehicles crossing the view
        at up to half their width a frame) is kept. ``False``: every velocity but the size's.
    exit_outside: a lost track whose predicted box has more than this fraction of its area
        outside the picture is dropped: the vehicle left through the border, and a vehicle
        entering there later gets an id of its own instead of the one of the vehicle that left.
        A leaving vehicle's boxes are cut at the border, so a lost track, which keeps the size
        of its last box and moves at the speed of its centre (half the vehicle's while the box
        shrinks), lags the vehicle: when a quarter of the prediction is outside, the vehicle
        shows about half of what it showed when it was lost. Needs the frame's size
        (``Tracker.update(..., frame_shape=)``). ``None``: a lost track is kept ``max_lost``
        frames wherever it is predicted.
    exit_after: ``exit_outside`` drops a track only once it has missed at least this many
        frames in a row (before the current one). After one missed frame the prediction is one
        step from a box cut at the border, and the box found next is as often what is left of
        the same vehicle (which ``--offline`` then joins across the missed frame) as another
        vehicle.
    max_gap: ``--offline`` only: a track's gaps of at most this many frames are filled by
        linear interpolation (StrongSORT's gap interpolation, Du et al., 2023).
    """

    _OMIT_NONE = ("cut_shape", "exit_outside", "max_behind")  # configs written before it existed keep their digest
    #: the queue gate's fields, the cut's shape test and the offline extension back, deleted
    #: (docs/accuracy.md, "Deleted stages"), at their off values: the dicts written with them
    #: still load, the digests as before
    _RETIRED = MappingProxyType({"max_behind": None, "behind_speed": 0.1, "cut_shape": None, "extend_back": 0})

    low_heat: float = 0.5
    match_iou: float = 0.2
    low_match_iou: float = 0.5
    tentative_match_iou: float = 0.3
    min_hits: int = 1
    max_lost: int = 30
    split_overlap: float = 0.5
    output: Literal["detection", "filtered"] = "detection"
    buffer: float = 0.3
    std_position: float = 1 / 20
    std_velocity: float = 1 / 160
    init_velocity: float = 0.25
    hold_row: bool = True
    exit_outside: float | None = 0.25
    exit_after: int = 2
    max_gap: int = 10

    def __post_init__(self) -> None:
        if not 0 <= self.low_heat < 1:
            raise ValueError(f"low_heat must be in [0, 1), got {self.low_heat!r}")
        for name in ("match_iou", "low_match_iou", "tentative_match_iou"):
            v = getattr(self, name)
            if not 0 < v <= 1:
                raise ValueError(f"{name} must be in (0, 1], got {v!r}")
        for name, lo in (("min_hits", 1), ("max_lost", 0), ("max_gap", 0), ("exit_after", 1)):
            v = getattr(self, name)
            if int(v) != v or v < lo:
                raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
        if not 0 <= self.split_overlap <= 1:
            raise ValueError(f"split_overlap must be in [0, 1], got {self.split_overlap!r}")
        if not 0 <= self.buffer <= 2:
            raise ValueError(f"buffer must be in [0, 2], got {self.buffer!r}")
        if self.exit_outside is not None and not 0 <= self.exit_outside < 1:
            raise ValueError(f"exit_outside must be in [0, 1) or None, got {self.exit_outside!r}")
        if not isinstance(self.hold_row, bool):
            raise ValueError(f"hold_row must be True or False, got {self.hold_row!r}")
        if self.output not in ("detection", "filtered"):
            raise ValueError(f"output must be 'detection' or 'filtered', got {self.output!r}")
        for name in ("std_position", "std_velocity", "init_velocity"):
            v = getattr(self, name)
            if not 0 < v < float("inf"):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")

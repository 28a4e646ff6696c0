"""How ``python -m fastdet adapt`` fits a main model to one camera (:class:`AdaptConfig`;
the work itself: :mod:`fastdet.train.adapt`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ._base import Config

#: the decision offsets tried for the operating point (decision units; + is stricter): whole
#: steps up to 4, then 6 and 8 (an adapted model's decision values spread over about +-15 units,
#: so -1..2 moved it little: docs/training.md has the measurements)
DEFAULT_OFFSETS: tuple[float, ...] = (-1.0, 0.0, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0)


#: the side-view component's decision offsets tried (decision units; + is stricter): its
#: logistic regression's probability 0.5 to 0.998
DEFAULT_SIDE_OFFSETS: tuple[float, ...] = (0.0, 1.0, 2.0, 3.0, 4.0, 6.0)


def _whole(name: str, v: object, low: int) -> None:
    if isinstance(v, bool) or not isinstance(v, int) or v < low:
        raise ValueError(f"{name} must be a whole number >= {low}, got {v!r}")


@dataclass(frozen=True)
class AdaptConfig(Config):
    """Settings of an adaptation run.

    every: frames are sampled every ``every``-th frame of each video from frame 1 (at least;
        more apart when ``max_frames`` asks for it).
    max_frames: at most this many sampled frames over all the footage, spread evenly (the
        sampling step grows to ``ceil(total frames / max_frames)``).
    holdout: the fraction of each video, at its end, kept aside for the operating point
        (contiguous: the pipeline's heat map needs consecutive frames); never trained on.
    holdout_max: at most this many frames kept aside over all the footage (split evenly
        between the videos): the pipeline runs over them three or four times (the bundled model,
        every offset at once, the side-view component's offsets at once, the offset chosen), a
        large part of a run's time on long footage (docs/benchmarks.md, "Adapting to a camera").
    holdout_every: the teacher labels every ``holdout_every``-th frame of the kept-aside stretch
        (from its first): the operating point's evidence. 1: every frame (at most ``holdout_max``;
        the teacher's cost is small beside the rest), so that on a short clip the choice does not
        rest on the 4-7 frames every 5th leaves it (docs/training.md, "Every kept-aside frame
        labelled").
    hold_bytes: the kept-aside frames are decoded once (reaching them decodes every frame
        before them: 41 s into 10 minutes of 1280x720 footage) and held for those runs
        (:func:`fastdet.io.hold.hold_frames`): in memory while they take at most this many
        bytes over all the videos (400 frames of 1280x720, the default cap, are 1.1 GB), the
        rest in raw files in the work folder (400 of 1920x1080: 2.5 GB), removed when the step
        ends; 0: all in files. Where a file cannot be written (a full disk), each run decodes
        its way to the stretch again, as before (the same boxes, slower).
    weight: the sample weight of every camera crop in the fit (each bundled crop weighs 1): a
        crop counts as this many copies of it, without the copies' memory.
    jitter: shifted / rescaled copies of every positive crop (besides the crop itself).
    negatives_per_picture: random background windows cut from each sampled frame.
    hard_per_picture: at most this many hard negatives (windows the bundled model fires on
        that touch no labelled box) from each sampled frame.
    mining_rounds: how many times hard negatives are mined: first with the bundled model, then
        with each round's fitted model (the windows it still fires on that touch no labelled
        box, ``hard_per_picture`` a frame), each round's crops added to the next fit; 1: the
        bundled model's only.
    mining_frames: the rounds after the first search at most this many of the frames trained on,
        spread evenly (a round searches every window of a frame at every scale: 0.24 s a 1280x720
        frame, 92 s for the 385 frames of 10 minutes of footage).
    own_box_weight: the camera's box regressor learns from the jittered boxes about each
        labelled vehicle and from the boxes the camera's model itself finds on the frames trained
        on (its positive windows at the video search's bands, after non-maximum suppression, each
        paired with the labelled vehicle it overlaps at IoU >= 0.3), each of these counted this
        many times; 0: the jittered boxes only (docs/training.md, "The regressor learns from the
        model's own boxes").
    side_aspect: a labelled vehicle at least this many times as wide as tall (and 32 px wide) is a
        positive of the camera's side-view component (:mod:`fastdet.train.side`).
    side_min_vehicles: the fewest such vehicles the component is fitted on (fewer: none).
    side_jitter, side_negatives, side_hard: its crops: jittered copies of each positive, random
        background windows a frame, hard negatives a frame (one round).
    side_C: its logistic regression's inverse penalty.
    side_offsets: its decision offsets tried on the kept-aside footage with the chosen box
        formation and offset; leaving it out is tried too, and the rule of ``offsets`` picks
        (:func:`fastdet.train.operating_point.choose_side_offset`).
    min_score: a teacher vehicle at least this sure is a target, below it an ignore region.
    offsets: the decision offsets (:func:`fastdet.train.blend.offset`, decision units; + is
        stricter) tried on the kept-aside footage; the strictest whose F1 against the teacher is
        within one standard error of the best wins (:func:`fastdet.train.operating_point.strictest_within_one_se`).
    C, truncate, truncate_keep, reencode: the training recipe (default: the bundled model's).
    max_per_folder: at most this many crops of each bundled crop folder (``None``: all; for
        quick runs and tests).
    seed: random seed (crops, classifier).
    """

    every: int = 5
    max_frames: int = 400
    holdout: float = 0.2
    holdout_max: int = 400
    holdout_every: int = 1
    hold_bytes: int = 1536 * 2**20
    weight: int = 4
    jitter: int = 2
    negatives_per_picture: int = 8
    hard_per_picture: int = 20
    mining_rounds: int = 2
    mining_frames: int = 120
    own_box_weight: int = 4
    side_aspect: float = 1.4
    side_min_vehicles: int = 20
    side_jitter: int = 3
    side_negatives: int = 30
    side_hard: int = 30
    side_C: float = 0.01
    side_offsets: tuple[float, ...] = DEFAULT_SIDE_OFFSETS
    min_score: float = 0.3
    offsets: tuple[float, ...] = DEFAULT_OFFSETS
    C: float = 0.0218
    truncate: float = 0.25
    truncate_keep: tuple[float, float] = (0.75, 0.875)
    reencode: float = 0.25
    max_per_folder: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        _whole("every", self.every, 1)
        _whole("max_frames", self.max_frames, 2)
        _whole("holdout_max", self.holdout_max, 1)
        _whole("holdout_every", self.holdout_every, 1)
        _whole("hold_bytes", self.hold_bytes, 0)
        _whole("weight", self.weight, 1)
        _whole("jitter", self.jitter, 0)
        _whole("negatives_per_picture", self.negatives_per_picture, 0)
        _whole("hard_per_picture", self.hard_per_picture, 0)
        _whole("mining_rounds", self.mining_rounds, 1)
        _whole("mining_frames", self.mining_frames, 1)
        _whole("own_box_weight", self.own_box_weight, 0)
        _whole("side_min_vehicles", self.side_min_vehicles, 1)
        _whole("side_jitter", self.side_jitter, 0)
        _whole("side_negatives", self.side_negatives, 0)
        _whole("side_hard", self.side_hard, 0)
        for name in ("side_aspect", "side_C"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a number > 0, got {v!r}")
        if not self.side_offsets or not all(isinstance(o, (int, float)) and math.isfinite(o)
                                            for o in self.side_offsets):
            raise ValueError(f"side_offsets must be finite numbers, at least one, got {self.side_offsets!r}")
        object.__setattr__(self, "side_offsets", tuple(sorted({float(o) for o in self.side_offsets})))
        if self.max_per_folder is not None:
            _whole("max_per_folder", self.max_per_folder, 1)
        if not (isinstance(self.holdout, (int, float)) and 0 < self.holdout < 1):
            raise ValueError(f"holdout must be a fraction in (0, 1), got {self.holdout!r}")
        if not (isinstance(self.min_score, (int, float)) and 0 <= self.min_score <= 1):
            raise ValueError(f"min_score must be 0 to 1, got {self.min_score!r}")
        if not self.offsets or not all(isinstance(o, (int, float)) and math.isfinite(o) for o in self.offsets):
            raise ValueError(f"offsets must be finite numbers, at least one, got {self.offsets!r}")
        object.__setattr__(self, "offsets", tuple(sorted({float(o) for o in self.offsets})))
        if not (isinstance(self.C, (int, float)) and math.isfinite(self.C) and self.C > 0):
            raise ValueError(f"C must be > 0, got {self.C!r}")
        for name in ("truncate", "reencode"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0 <= v <= 1):
                raise ValueError(f"{name} must be a fraction in [0, 1], got {v!r}")
        k0, k1 = self.truncate_keep
        if not 0 < k0 <= k1 <= 1:
            raise ValueError(f"truncate_keep must satisfy 0 < A <= B <= 1, got {self.truncate_keep!r}")

    def step(self, total_frames: int) -> int:
        """The sampling step over footage of ``total_frames`` frames: ``every``, or larger so
        that at most about ``max_frames`` frames are sampled."""
        return max(self.every, math.ceil(total_frames / self.max_frames))

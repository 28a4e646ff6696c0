"""A main model fitted to one camera from its own footage (``python -m fastdet adapt``).

The steps, each a function here (the command, :mod:`fastdet.cli.adapt`, runs them in turn):

1. :func:`plan_footage`: the videos of one camera (all of one frame size), the frames sampled
   from them (every ``step``-th frame from frame 1, ``step`` = ``every`` or more so that at most
   ``max_frames`` are sampled) and the stretch at the end of each video kept aside for the
   operating point (contiguous: the heat map needs consecutive frames; it is never trained on,
   and its frames are labelled every ``holdout_every``-th frame from its first: every frame by default);
2. :func:`label_clips`: the teacher CNN boxes the planned frames of each video; each video's
   labels are written to the work folder (``CLIP-KEY.teacher.txt`` + ``CLIP-KEY.frames``,
   :func:`~fastdet.teacher.label.write_teacher_files`) when the video is done, so a stopped run
   resumes with the next video and a finished video is never labelled again;
3. :func:`camera_crops`: crops of the sampled frames outside the kept-aside stretch (positives
   around the teacher's targets with jittered copies, background negatives, hard negatives the
   bundled model fires on);
4. :func:`fit_camera_model`: the main model trained from the bundled crop folders plus those
   crops (each of sample weight ``weight``: as if repeated that many times, without the copies'
   memory), with the bundled model's recipe, in float32 features (half the memory of float64);
5. :func:`fit_camera_regressor`: the box regressor refitted on the camera alone (jittered copies
   of the labelled targets of the same frames, and their mirror images), carried in the model
   file (:attr:`~fastdet.model.Model.regressor`), so ``video --model`` refines the camera's boxes
   with it: the video pipeline's boxes come from heat blobs, which for an adapted model reach the
   targets far less often than its windows do, and the regressor puts them on the vehicle
   (docs/training.md, "The camera's own box regressor");
6. :func:`choose_operating_point`: the kept-aside stretches run through the video pipeline with
   the new model moved by each of a few decision offsets (:func:`~fastdet.train.blend.offset`),
   with either box formation (the heat map's, or each frame's windows after suppression); each
   frame read and scored once for all of them (:mod:`fastdet.video.replay`); the formation and
   offset of best F1 against the labels of those frames kept. The pipeline and the scoring are given by the
   caller (the ``video`` and ``eval`` layers sit beside this one).
"""
from __future__ import annotations

import hashlib
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from .. import signals as _signals
from ..config import JitterConfig
from ..config.adapt import AdaptConfig
from ..detect.regressor import BoxRegressor
from ..errors import DataError
from ..io.reader import FrameReader
from ..labels.load import load_pictures
from ..labels.picture import AnnotatedPicture
from ..labels.teacher import read_teacher_clip
from ..model import Model
from ..teacher.label import Labelled, teacher_paths, write_teacher_files
from ..teacher.yolox import TeacherDetector
from .dataset import CropSet
from .fit import train
from .pictures import hard_negative_crops, picture_crops
from .refine import View, fit_cascade, jittered_views, large_enough, matched_inputs, mirror

#: the camera id of every adapted picture
CAMERA = "adapt"
#: the fewest labelled vehicles (of :data:`~fastdet.train.refine.MIN_VEHICLE_PX` and more) the
#: camera's own box regressor is fitted on; with fewer the model keeps the bundled regressor.
#: The cameras measured had 61-383 (docs/training.md, "The camera's own box regressor"); a fit
#: on a handful would be unmeasured
MIN_REGRESSOR_VEHICLES = 50


@dataclass(frozen=True)
class Clip:
    """One video of the footage.

    path: the video file; name: its name without extension (unique in the footage);
    frames: its frame count (from the header); holdout_start: the first (1-based) frame of the
    stretch kept aside, which runs to the last frame.
    """

    path: str
    name: str
    frames: int
    holdout_start: int

    @property
    def key(self) -> str:
        """``NAME-HASH``: the name of the video's label files in the work folder; the hash (8
        hex digits) of its real path, size and modification time, so a changed video is labelled anew."""
        st = os.stat(self.path)
        h = hashlib.sha256(f"{os.path.realpath(self.path)}|{st.st_size}|{st.st_mtime_ns}".encode()).hexdigest()
        return f"{self.name}-{h[:8]}"

    def train_frames(self, step: int) -> list[int]:
        """The sampled frames before the kept-aside stretch: 1, 1 + step, ..."""
        return list(range(1, self.holdout_start, step))

    def holdout_frames(self, every: int) -> list[int]:
        """The labelled frames of the kept-aside stretch: its first, then every ``every``-th."""
        return list(range(self.holdout_start, self.frames + 1, every))

    def planned(self, step: int, every: int) -> list[int]:
        """Every frame the teacher labels, in order."""
        return self.train_frames(step) + self.holdout_frames(every)


@dataclass(frozen=True)
class Footage:
    """The planned footage: ``clips``, the sampling ``step`` (frames), ``holdout_every`` (the
    kept-aside stretch's labelling step, :attr:`AdaptConfig.holdout_every`) and the frame
    ``size`` ``(width, height)`` px."""

    clips: tuple[Clip, ...]
    step: int
    holdout_every: int
    size: tuple[int, int]

    @property
    def n_train(self) -> int:
        return sum(len(c.train_frames(self.step)) for c in self.clips)

    @property
    def n_holdout(self) -> int:
        return sum(len(c.holdout_frames(self.holdout_every)) for c in self.clips)

    def planned(self, clip: Clip) -> list[int]:
        """Every frame of ``clip`` the teacher labels, in order: its sampled frames (every
        ``step``-th) then its kept-aside stretch's (every ``holdout_every``-th)."""
        return clip.planned(self.step, self.holdout_every)

    @property
    def holdout_length(self) -> int:
        """Frames in the kept-aside stretches (what each pipeline run reads)."""
        return sum(c.frames - c.holdout_start + 1 for c in self.clips)


def _frame_count(reader: FrameReader, path: str) -> int:
    """The video's frame count: the header's, else counted by decoding (one pass)."""
    if reader.frame_count is not None:
        return reader.frame_count
    n = sum(1 for _ in reader)
    if n < 1:
        raise DataError(f"{path}: the video has no frames")
    return n


def plan_footage(videos: Sequence[str], config: AdaptConfig) -> Footage:
    """Open every video (its first frame decoded), check that all have one frame size and
    plan the sampling (module docstring). Raises :class:`~fastdet.errors.DataError` in one line
    for no video, a video that does not open, two videos of one name, mixed frame sizes, or a
    plan with no frame to train on or none kept aside."""
    if not videos:
        raise DataError("no video files in the footage")
    names: dict[str, str] = {}
    opened: list[tuple[str, str, int]] = []
    size: tuple[int, int] | None = None
    first = ""
    for v in videos:
        name = Path(v).stem
        if name in names:
            raise DataError(f"{v} and {names[name]}: two videos named {name!r}; give each video its own name")
        names[name] = v
        with FrameReader(v, notify=lambda _n: None) as reader:
            h, w = reader.shape[:2]
            n = _frame_count(reader, v)
        if size is None:
            size, first = (w, h), v
        elif (w, h) != size:
            raise DataError(f"{v}: frames are {w}x{h}, {first}'s are {size[0]}x{size[1]}: the footage of one "
                            f"camera has one frame size (adapt each camera on its own)")
        opened.append((v, name, n))
    assert size is not None
    total = sum(n for _, _, n in opened)
    step = config.step(total)
    cap = max(1, config.holdout_max // len(opened))
    clips = []
    for v, name, n in opened:
        kept = min(max(1, round(config.holdout * n)), cap, n - 1) if n > 1 else 0
        clips.append(Clip(v, name, n, n - kept + 1))
    fp = Footage(tuple(clips), step, config.holdout_every, size)
    if fp.n_train == 0:
        raise DataError(f"the footage ({total} frames) leaves no frame to train on before the kept-aside "
                        f"{config.holdout:.0%} at the end of each video")
    if fp.n_holdout == 0:
        raise DataError(f"the footage ({total} frames) leaves no frame kept aside for the operating point: "
                        f"the videos are too short")
    return fp


def label_key(teacher: str | os.PathLike[str], size: int | None, floor: float) -> str:
    """The work folder's labels subfolder for a teacher file and its settings: ``labels-HASH``
    (a changed teacher, input size or score floor labels anew)."""
    st = os.stat(teacher)
    h = hashlib.sha256(f"{os.path.realpath(teacher)}|{st.st_size}|{st.st_mtime_ns}|{size}|{floor}".encode())
    return f"labels-{h.hexdigest()[:12]}"


def cached_labels(folder: Path, clip: Clip, footage: Footage) -> Path | None:
    """The clip's teacher file in ``folder`` when it is there, complete and of the planned
    frames (else ``None``: the clip is labelled)."""
    boxes, frames = teacher_paths(folder, clip.key)
    if not (boxes.is_file() and frames.is_file()):
        return None
    try:
        listed = [int(line) for line in frames.read_text().split()]
    except (OSError, ValueError):
        return None
    return boxes if listed == footage.planned(clip) else None


#: labels the clips given, yielding each clip's labels (its planned frames) as it is done, in
#: any order; a stop signal ends it early (it then returns without the unfinished clips)
Labeller = Callable[[Sequence["Clip"], "Footage"], Iterator[tuple["Clip", list[Labelled]]]]


def local_labeller(detector: TeacherDetector, progress: bool = True) -> Labeller:
    """A :data:`Labeller` running ``detector`` here, one clip after the other (a bar each)."""

    def label(clips: Sequence[Clip], footage: Footage) -> Iterator[tuple[Clip, list[Labelled]]]:
        for clip in clips:
            want = set(footage.planned(clip))
            last = max(want)
            labelled: list[Labelled] = []
            bar = tqdm(total=len(want), unit="frame", desc=f"teacher {clip.name}", file=sys.stderr,
                       dynamic_ncols=True, disable=not progress)
            try:
                with FrameReader(clip.path) as reader:
                    for fno, frame, _ in reader:
                        if _signals.stop_requested():
                            break
                        if fno in want:
                            labelled.append((fno, detector.detect(frame)))
                            bar.update(1)
                        if fno >= last:
                            break
            finally:
                bar.close()
            if _signals.stop_requested():
                return
            yield clip, labelled

    return label


def label_clips(footage: Footage, detector: TeacherDetector, folder: Path, progress: bool = True,
                log: Callable[[str], None] = print, labeller: Labeller | None = None) -> tuple[dict[str, Path], int]:
    """The teacher's labels of every clip's planned frames: ``({clip name: CLIP-KEY.teacher.txt},
    frames labelled now)``: ``detector`` run here (:func:`local_labeller`), or ``labeller``
    (``fastdet.batch.labelling`` labels on a Dask cluster). A clip labelled
    before (:func:`cached_labels`) is not labelled again; each other clip's files are written
    when it is done. Runs inside :func:`fastdet.signals.deferred`: a stop signal ends the run
    after the current frame (the clips not done get no files) and raises
    :class:`~fastdet.signals.Stopped`."""
    folder.mkdir(parents=True, exist_ok=True)
    label = labeller if labeller is not None else local_labeller(detector, progress)
    out: dict[str, Path] = {}
    n_now = 0
    with _signals.deferred(raise_on_exit=False):
        todo: list[Clip] = []
        for clip in footage.clips:
            found = cached_labels(folder, clip, footage)
            if found is None:
                todo.append(clip)
                continue
            out[clip.name] = found
            log(f"{clip.name}: teacher labels of {len(footage.planned(clip))} frames "
                f"read from {found.parent}")
        for clip, labelled in label(todo, footage):
            boxes, _ = write_teacher_files(folder, clip.key, labelled)
            out[clip.name] = boxes
            n_now += len(labelled)
            if _signals.stop_requested():
                break
    signum = _signals.received()
    if signum is not None:
        raise _signals.Stopped(signum, f"{len(out)} of {len(footage.clips)} videos labelled (kept in {folder}: "
                                       f"the next run goes on from there); no model written")
    return out, n_now


def teacher_pictures(footage: Footage, labels: dict[str, Path], min_score: float) -> list[AnnotatedPicture]:
    """The labelled frames of every clip as pictures (camera :data:`CAMERA`), in clip and frame
    order."""
    pics: list[AnnotatedPicture] = []
    for clip in footage.clips:
        pics.extend(read_teacher_clip(labels[clip.name], min_score=min_score, camera=CAMERA, video=clip.path,
                                      source=f"teacher:{clip.name}"))
    return pics


def split_pictures(footage: Footage, pictures: Sequence[AnnotatedPicture]
                   ) -> tuple[list[AnnotatedPicture], dict[str, list[AnnotatedPicture]]]:
    """``(training pictures, {clip name: its kept-aside pictures})``: a frame of a footage video
    at or after its ``holdout_start`` is kept aside; every other picture (a still, another
    video's frame) trains."""
    by_path = {os.path.realpath(c.path): c for c in footage.clips}
    train_pics: list[AnnotatedPicture] = []
    held: dict[str, list[AnnotatedPicture]] = {c.name: [] for c in footage.clips}
    for p in pictures:
        clip = by_path.get(os.path.realpath(p.path)) if p.frame is not None else None
        if clip is not None and p.frame is not None and p.frame >= clip.holdout_start:
            held[clip.name].append(p)
        else:
            train_pics.append(p)
    return train_pics, held


def ticking(pictures: Sequence[AnnotatedPicture], desc: str, progress: bool
            ) -> Iterator[tuple[AnnotatedPicture, np.ndarray]]:
    """Every picture with its pixels (:func:`~fastdet.labels.load.load_pictures`), a progress
    bar ``desc`` ticking a frame each (shown with ``progress``)."""
    bar = tqdm(total=len(pictures), unit="frame", desc=desc, file=sys.stderr, dynamic_ncols=True,
               disable=not progress)
    try:
        for item in load_pictures(pictures):
            yield item
            bar.update(1)
    finally:
        bar.close()


def camera_crops(pictures: Sequence[AnnotatedPicture], bundled: Model, config: AdaptConfig,
                 progress: bool = True) -> tuple[CropSet, dict[str, int], dict[str, float]]:
    """The camera's training crops of the window size, ``(N, 64, 64, 3) uint8`` in a
    :class:`~fastdet.train.dataset.CropSet`, each once (:func:`fit_camera_model` weighs them
    ``config.weight``); with their counts (``positives``, ``negatives``, ``hard_negatives``,
    and ``weight``) and the seconds of each step (``crops``, ``hard_negatives``)."""
    t0 = time.perf_counter()
    base = picture_crops(pictures, bundled.config, jitter=config.jitter,
                         negatives_per_picture=config.negatives_per_picture, seed=config.seed,
                         frames=ticking(pictures, "crops", progress))
    t1 = time.perf_counter()
    hard = mine_hard_negatives(pictures, bundled, config, 1, progress)
    t2 = time.perf_counter()
    crops = base if hard is None or not len(hard) else CropSet.concat(base, hard)
    counts = {"positives": int((base.labels == 1).sum()), "negatives": int((base.labels == 0).sum()),
              "hard_negatives": 0 if hard is None else len(hard), "weight": config.weight}
    return crops, counts, {"crops": t1 - t0, "hard_negatives": t2 - t1}


def spread(items: Sequence[Any], n: int) -> list[Any]:
    """At most ``n`` of ``items``, spread evenly over them (all of them when there are at most
    ``n``), in their order."""
    if len(items) <= n:
        return list(items)
    return [items[i] for i in np.linspace(0, len(items) - 1, n).round().astype(int)]


def mine_hard_negatives(pictures: Sequence[AnnotatedPicture], model: Model, config: AdaptConfig, round_: int,
                        progress: bool = True) -> CropSet | None:
    """Mining round ``round_`` (1: with the bundled model): at most ``config.hard_per_picture``
    windows a frame of ``pictures`` that ``model`` fires on and that touch no labelled box (the
    whole frame searched, :func:`~fastdet.train.pictures.hard_negative_crops`); ``None`` when
    ``hard_per_picture`` is 0. Each round draws with its own seed."""
    if not config.hard_per_picture:
        return None
    desc = "hard negatives" if round_ == 1 else f"hard negatives (round {round_})"
    return hard_negative_crops(model, pictures, per_picture=config.hard_per_picture, min_score=0.0,
                               seed=config.seed + round_ - 1, frames=ticking(pictures, desc, progress),
                               cells_per_step=2, steps=2, threshold=0.0)


def fit_mined_camera_model(data: Path, bundled: Model, pictures: Sequence[AnnotatedPicture], crops: CropSet,
                           counts: dict[str, int], config: AdaptConfig, progress: bool = True,
                           log: Callable[[str], None] = print) -> tuple[Model, dict[str, float]]:
    """:func:`fit_camera_model` on ``crops`` (:func:`camera_crops`' of ``pictures``), then
    ``config.mining_rounds - 1`` more rounds: hard negatives mined with the model just fitted
    (:func:`mine_hard_negatives`) on at most ``config.mining_frames`` of ``pictures``, spread
    evenly (:func:`spread`), added to the crops, the model fitted again. A round that finds
    none ends the rounds. ``counts["hard_negatives"]`` grows by each round's;
    returns the last model and the seconds (``train``: every fit; ``hard_negatives``: the
    rounds after the first)."""
    t = time.perf_counter()
    model = fit_camera_model(data, bundled, crops, config, progress, log)
    secs = {"train": time.perf_counter() - t, "hard_negatives": 0.0}
    later = spread(pictures, config.mining_frames)
    for r in range(2, config.mining_rounds + 1):
        _signals.check()
        t = time.perf_counter()
        hard = mine_hard_negatives(later, model, config, r, progress)
        secs["hard_negatives"] += time.perf_counter() - t
        if hard is None or not len(hard):
            break
        log(f"round {r}: {len(hard)} hard negatives the round-{r - 1} model fires on")
        crops = CropSet.concat(crops, hard)
        counts["hard_negatives"] += len(hard)
        t = time.perf_counter()
        model = fit_camera_model(data, bundled, crops, config, progress, log)
        secs["train"] += time.perf_counter() - t
    return model, secs


def fit_camera_model(data: Path, bundled: Model, crops: CropSet, config: AdaptConfig, progress: bool = True,
                     log: Callable[[str], None] = print) -> Model:
    """The main model trained on the bundled crop folders of ``data`` plus ``crops`` of sample
    weight ``config.weight`` (logistic regression, the bundled model's features, ``config``'s
    recipe; no held-out split). The features are float32: the training matrix of the bundled
    crops and their copies (about 45,000 rows of 12,576 features) takes 2.2 GB instead of 4.5."""
    model, _ = train(data, bundled.config, "logreg", config.C, split="none", seed=config.seed,
                     max_per_folder=config.max_per_folder, progress=progress, truncate=config.truncate,
                     truncate_keep=config.truncate_keep, reencode=config.reencode, extra_crops=crops,
                     extra_weight=float(config.weight), dtype=np.float32, log=log)
    assert model is not None
    return model


def fit_camera_regressor(pictures: Sequence[AnnotatedPicture], bundled: BoxRegressor, config: AdaptConfig,
                         progress: bool = True, own_boxes: Callable[[np.ndarray], np.ndarray] | None = None
                         ) -> tuple[BoxRegressor | None, dict[str, Any]]:
    """The box regressor of the camera: one ridge stage on ``bundled``'s features (its
    :attr:`~BoxRegressor.spec`), its penalty chosen by cross-validation over folds that keep a
    vehicle on one side (:func:`~fastdet.train.refine.fit_cascade`), fitted on

    - the jittered boxes about each labelled target of ``pictures`` and as many in the mirrored
      frame (:class:`~fastdet.config.JitterConfig`'s, as the bundled regressor's; ``config.seed``
      draws them; :func:`~fastdet.train.refine.jittered_views`);
    - with ``own_boxes`` (a frame ``(H, W, 3) uint8 BGR`` -> the boxes ``(N, 4)`` the camera's
      model finds on it) and ``config.own_box_weight``: those boxes of every picture, each paired
      with the target it overlaps most when their IoU is at least ``JitterConfig.min_iou``
      (:func:`~fastdet.train.refine.matched_inputs`), and mirrored, each counted
      ``own_box_weight`` times. The windows the model fires on are not the jitter's: a square
      window on the side of a parked car, a part of a truck.

    Returns it with its fit's report (samples, vehicles, own boxes, the penalty, the
    cross-validated mean IoU before and after one step); ``(None, {"groups": n})`` when the
    pictures hold fewer than :data:`MIN_REGRESSOR_VEHICLES` vehicles of 4 px and more (the model
    keeps the bundled one)."""
    def usable(t: np.ndarray) -> np.ndarray:  # what jittered_views cuts boxes about
        return np.asarray(t, np.float64).reshape(-1, 4)[large_enough(t)]

    vehicles = sum(len(usable(p.targets)) for p in pictures)
    if vehicles < MIN_REGRESSOR_VEHICLES:
        return None, {"groups": vehicles}
    jitter = JitterConfig()
    frames, own, group = [], [], 0
    for pic, image in ticking(pictures, "box regressor", progress):
        t = usable(pic.targets)
        if len(t):
            groups = np.arange(group, group + len(t))
            frames.append((image, t, groups))
            group += len(t)
            if own_boxes is not None and config.own_box_weight:
                b, bt, bg = matched_inputs(own_boxes(image), t, groups, jitter.min_iou)
                if len(b):
                    v = View(image, b, bt, bg, config.own_box_weight)
                    own += [v, mirror(v)]
    views = jittered_views(frames, seed=config.seed, jitter=jitter) + own
    (arrays, report), = fit_cascade(views, bundled.spec, 1)
    report = {k: report[k] for k in ("samples", "groups", "alpha", "input_mean_iou", "output_mean_iou")}
    report["own_boxes"] = sum(len(v.inputs) for v in own) // 2
    reg = BoxRegressor.stack([BoxRegressor.from_fit(bundled.spec, *arrays)], metadata={
        "trained_on": "the camera's labelled frames (fastdet adapt)", "fit": report,
        "refine_config_of": "the pipeline's (RefineConfig)"})
    return reg, report

"""``python -m fastdet adapt``: a main model fitted to one camera from its own footage.

``python -m fastdet adapt FOOTAGE... (--teacher MODEL.onnx | --frames SPEC) -o MYCAM.npz
[--every N] [--max-frames M] [--holdout F] [--weight W] [--offsets O...] [--teacher-size PX]
[--threads N] [--workers N | --scheduler ADDRESS] [--data DIR] [--max-per-folder N] [--seed S]
[--no-progress]``

- FOOTAGE: video files, or folders whose video files are all taken, of one camera (one frame
  size). Frames are sampled every N-th frame (more apart when more than M would be sampled);
  the last ``--holdout`` fraction of each video is kept aside for the operating point, every
  frame of it labelled (``AdaptConfig.holdout_every``).
- ``--teacher``: a YOLOX-style ONNX detector labels the sampled frames (its boxes of score
  >= 0.3 of car / bus / truck are targets, lower ones and motorcycles ignore regions). Its
  labels are kept per video in the work folder ``.MYCAM.adapt/`` beside the output, so a
  stopped run goes on where it was and never labels a finished video again. With
  ``--workers N`` (a local Dask cluster of N processes) or ``--scheduler tcp://host:8786`` (a
  running one, as ``batch`` uses; needs ``fastdet[cluster]``) each video is labelled by a task
  of its own (:mod:`fastdet.batch.labelling`).
  ``--frames SPEC`` instead: the user's own labels (:mod:`fastdet.labels.sets`); those of
  FOOTAGE frames in the kept-aside stretch set the operating point (none: the model's own).
- The main model is trained from the bundled crop folders (``--data``, default
  ``$FASTDET_DATA``) plus the camera's crops (each of sample weight ``--weight``; hard
  negatives mined with the bundled model, then again with the model fitted, which is fitted
  again); the box regressor is fitted on the camera's labelled vehicles (jittered boxes about
  them and the model's own window boxes on them, :func:`own_window_boxes`) and carried in the
  model file; the model is then given the box formation (heat map or windows) of best F1 against
  the labels of the kept-aside frames, and moved by the strictest decision offset within one
  standard error of that formation's best F1 (:func:`fastdet.train.operating_point.strictest_within_one_se`),
  through the ``video`` pipeline with that regressor (:mod:`fastdet.train.adapt`), at the horizon
  a run of each whole video has (:func:`~fastdet.video.run.file_horizon`).
  A side-view component (:mod:`fastdet.train.side`) is fitted on the camera's wide vehicles and
  kept, moved by the offset chosen for it, only where the kept-aside frames say so
  (:func:`fastdet.train.operating_point.choose_side_offset`, :func:`~fastdet.train.operating_point.use_side`;
  the summary's ``side``).
  Each kept-aside stretch is decoded once for the runs over it (:func:`held_stretches`:
  in memory up to ``AdaptConfig.hold_bytes``, the rest in raw files in the work folder, removed
  when the step ends).
- Writes ONE model file (``video / image / batch --model`` take it), its metadata holding the
  summary (``metadata["adapt"]``): frames, seconds per step, agreement with the labels of the
  kept-aside frames before (bundled model) and after, the pipeline's ms per frame (its steady
  frame loop over the held frames), how the kept-aside frames were held (``kept_aside``).
- Bad input is one line and exit 2 before any long work: no video or frames, a teacher that is
  not a YOLOX-style ONNX detector, mixed frame sizes, an output inside the installed package,
  a missing crop folder. A stop signal ends the run cleanly (no model; finished videos' labels kept).
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from .. import _numba
from .. import signals as _signals
from ..config import BOXES, REFERENCE_HORIZON, Boxes, PipelineConfig
from ..config.adapt import AdaptConfig
from ..data import data_dir
from ..detect.regressor import carrying, load_regressor
from ..detections import Detections
from ..errors import DataError, FastdetError, WriteError
from ..io.files import not_found
from ..io.held import HeldFrames
from ..io.hold import hold_frames
from ..io.paths import check_paths, is_inside
from ..labels.picture import AnnotatedPicture
from ..model import Model, load_model
from ..train import adapt as _adapt
from ..train import operating_point as _op
from ..train import side as _side
from ..train.blend import offset, side_offset
from ..video.detector import BOXES_KEY, HORIZON_KEY, ONCOMING_KEY
from ..video.horizon import MIN_BOXES, horizon_from_boxes
from ..video.run import file_horizon
from ._args import fraction, positive_int, teacher_size, video_files

PACKAGE_DIR = Path(__file__).resolve().parents[1]


def add_arguments(p: argparse.ArgumentParser) -> None:
    d = AdaptConfig()
    p.add_argument("footage", nargs="+", metavar="FOOTAGE", help="video files or folders of them, of one camera")
    p.add_argument("--teacher", default=None, metavar="MODEL.onnx",
                   help="a YOLOX-style ONNX detector that labels the frames (e.g. teachers/yolox_nano.onnx)")
    p.add_argument("--frames", default=None, metavar="SPEC",
                   help="your own labels instead of a teacher (FORMAT:PATH[,OPTION...], see docs/labels.md)")
    p.add_argument("-o", "--output", required=True, type=Path, metavar="MYCAM.npz", help="the model file to write")
    p.add_argument("--every", type=positive_int, default=d.every, metavar="N",
                   help=f"sample every N-th frame (default {d.every})")
    p.add_argument("--max-frames", type=positive_int, default=d.max_frames, metavar="M",
                   help=f"sample at most about M frames in all, spread evenly (default {d.max_frames})")
    p.add_argument("--holdout", type=fraction, default=d.holdout, metavar="F",
                   help=f"keep the last F of each video aside for the operating point (default {d.holdout:g})")
    p.add_argument("--weight", type=positive_int, default=d.weight, metavar="W",
                   help=f"each camera crop counts W times in the fit (a sample weight; default {d.weight})")
    p.add_argument("--offsets", type=float, nargs="+", default=list(d.offsets), metavar="O",
                   help="decision offsets tried for the operating point (default "
                        + " ".join(f"{o:g}" for o in d.offsets) + ")")
    p.add_argument("--teacher-size", type=teacher_size, default=None, metavar="PX",
                   help="the teacher's input width (default 640)")
    p.add_argument("--threads", type=positive_int, default=None, metavar="N", help="onnxruntime threads")
    p.add_argument("--workers", type=positive_int, default=None, metavar="N",
                   help="label the videos on a local Dask cluster of N worker processes, one video a task")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="label the videos on the Dask cluster of this scheduler, e.g. tcp://host:8786 (its "
                        "workers must see the same paths)")
    p.add_argument("--data", type=Path, default=None,
                   help="folder with the vehicles/ and non-vehicles/ crops (default: $FASTDET_DATA)")
    p.add_argument("--max-per-folder", type=positive_int, default=None, metavar="N",
                   help="use at most N crops of each bundled crop folder (quick runs)")
    p.add_argument("--seed", type=int, default=0, help="random seed")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")


def _config(args: argparse.Namespace) -> AdaptConfig:
    try:
        return AdaptConfig(every=args.every, max_frames=max(2, args.max_frames), holdout=args.holdout,
                           weight=args.weight, offsets=tuple(args.offsets), max_per_folder=args.max_per_folder,
                           seed=args.seed)
    except ValueError as exc:
        raise FastdetError(str(exc)) from None


def _check_output(out: Path, inputs: list[tuple[str, str]]) -> None:
    if out.suffix != ".npz":
        raise DataError(f"-o {out}: the model file's name must end in .npz")
    if is_inside(out.parent if out.parent != Path("") else Path("."), PACKAGE_DIR):
        raise DataError(f"-o {out}: is inside the installed fastdet package ({PACKAGE_DIR}); write your model "
                        f"elsewhere")
    check_paths(inputs, [("-o", out, "model")])


def _check_data(data: Path) -> None:
    for sub in ("vehicles", "non-vehicles"):
        if not (data / sub).is_dir():
            raise not_found(data / sub, f"crop folder {data / sub} not found (give --data or set FASTDET_DATA)")


def work_folder(out: Path) -> Path:
    """``.NAME.adapt/`` beside the output ``NAME.npz``: the teacher's labels, kept between runs."""
    return out.parent / f".{out.stem}.adapt"


def _gt(pictures: list[AnnotatedPicture]) -> Detections:
    """The kept-aside pictures' labels as a ground-truth table (:func:`~fastdet.eval.pictures.frames_ground_truth`)."""
    from ..eval.pictures import frames_ground_truth

    return frames_ground_truth(pictures, source="kept-aside labels")


def _predictions(tables: list[Detections]) -> Detections:
    """A run's per-frame tables (each with its ``frames`` column) as one table to score; one
    with an empty ``frames`` column when there is no box."""
    preds = Detections.concat(tables) if tables else Detections.empty()
    if preds.frames is None:
        preds = Detections(np.zeros((0, 4), np.int32), np.zeros(0, np.float32), frames=np.zeros(0, np.int64))
    return preds


@contextmanager
def held_stretches(footage: _adapt.Footage, held: Mapping[str, list[AnnotatedPicture]], config: AdaptConfig,
                   folder: Path) -> Iterator[dict[str, HeldFrames]]:
    """Each clip's kept-aside stretch (of a clip with labelled frames there) decoded once and
    held for the operating point's runs (:func:`fastdet.io.hold.hold_frames`), ``{clip name:
    HeldFrames}``: the stretch's frames, at least :data:`~fastdet.video.horizon.HORIZON_FRAMES`
    (what a run reads ahead for the horizon), in memory while they fit in
    ``config.hold_bytes`` over all clips, else in a raw file in ``folder``. A clip whose file
    cannot be written (a full disk) is left out, with a note: its runs decode the video up to
    the stretch themselves. Every held frame is dropped and every file removed when the block
    ends (a stop signal included; the files are also temporary names of
    :mod:`fastdet.io.atomic`, removed at exit)."""
    from ..video.horizon import HORIZON_FRAMES

    out: dict[str, HeldFrames] = {}
    budget = config.hold_bytes
    try:
        for clip in footage.clips:
            if not held.get(clip.name):
                continue
            n = max(clip.frames - clip.holdout_start + 1, HORIZON_FRAMES)
            try:
                frames = hold_frames(clip.path, clip.holdout_start - 1, n, max_bytes=budget, spill_dir=folder)
            except WriteError as exc:
                print(f"note: {exc}; each run decodes {clip.name} up to its kept-aside stretch instead "
                      f"(the same boxes, slower)", flush=True)
                continue
            out[clip.name] = frames
            if frames.spill is None:
                budget -= frames.nbytes
        yield out
    finally:
        for frames in out.values():
            frames.close()


@contextmanager
def _read_held(footage: _adapt.Footage, held: Mapping[str, list[AnnotatedPicture]], config: AdaptConfig,
               folder: Path) -> Iterator[tuple[dict[str, HeldFrames], float]]:
    """:func:`held_stretches`, with the seconds their reading took (the summary's ``kept_aside``)."""
    t = time.perf_counter()
    with held_stretches(footage, held, config, folder) as frames:
        yield frames, time.perf_counter() - t


def _source(clip: _adapt.Clip, frames: Mapping[str, HeldFrames] | None) -> str | HeldFrames:
    """What a run over ``clip``'s kept-aside stretch reads: its held frames, else the video."""
    return frames.get(clip.name, clip.path) if frames is not None else clip.path


def _horizon(horizons: Mapping[str, float | None] | None, clip: _adapt.Clip) -> float | str | None:
    return horizons[clip.name] if horizons is not None and clip.name in horizons else "auto"


def holdout_run(held: dict[str, list[AnnotatedPicture]], frames: Mapping[str, HeldFrames] | None = None,
                horizons: Mapping[str, float | None] | None = None) -> _op.HoldoutRun:
    """The video pipeline (:func:`fastdet.detect_video`, as ``video`` runs it) over a clip's
    kept-aside stretch with a model file, scored (:func:`fastdet.eval.evaluate`, IoU 0.5) on
    the clip's kept-aside labelled frames. ``frames``: the stretches held
    (:func:`held_stretches`; the same boxes as the video gives, without decoding it up to them).
    ``horizons``: each clip's horizon as a run of the whole video has it
    (:func:`~fastdet.video.run.file_horizon`; a clip not in it: estimated from the stretch's
    first frames)."""
    from ..eval.metrics import evaluate
    from ..video.run import detect_video

    def run(clip: _adapt.Clip, model: str | None) -> tuple[int, int, int, float, int]:
        pics = held.get(clip.name, [])
        if not pics:
            return 0, 0, 0, 0.0, 0
        # timed from the first frame out: the steady frame loop, not the start-up (reaching the
        # kept-aside stretch -- 40 s into 10 minutes of footage, when it is not held --, the
        # horizon's first frames)
        tables: list[Detections] = []
        t0 = 0.0
        for d in detect_video(_source(clip, frames), model=model, start=clip.holdout_start - 1,
                              frames=clip.frames - clip.holdout_start + 1, horizon=_horizon(horizons, clip)):
            if not tables:
                t0 = time.perf_counter()
            tables.append(d)
        secs = time.perf_counter() - t0 if tables else 0.0
        res = evaluate(_gt(pics), _predictions(tables), keyframes=np.array([p.frame for p in pics]), tracking=False)
        return res.tp, res.fp, res.fn, secs, max(len(tables) - 1, 0)

    return run


def holdout_lanes(held: dict[str, list[AnnotatedPicture]], frames: Mapping[str, HeldFrames] | None = None,
                  horizons: Mapping[str, float | None] | None = None) -> _op.LanesRun:
    """The video pipeline over a clip's kept-aside stretch for each lane -- a box formation and the
    model file moved by an offset --, the frames read and scored once for all of them
    (:func:`fastdet.video.replay.iter_lane_detections`: each lane's boxes are those of
    :func:`holdout_run` with the moved model and that formation), each lane's boxes scored as
    there. ``frames``, ``horizons``: as :func:`holdout_run`'s."""
    from ..eval.metrics import frame_counts
    from ..video.replay import iter_lane_detections

    def run(clip: _adapt.Clip, model: str, lanes: Sequence[_op.Lane]) -> tuple[dict[_op.Lane, np.ndarray], float, int]:
        pics = held.get(clip.name, [])
        if not pics:
            return {k: np.zeros((0, 3), np.int64) for k in lanes}, 0.0, 0
        t0 = time.perf_counter()
        config = replace(PipelineConfig(), model=model, horizon=_horizon(horizons, clip))
        tables: list[list[Detections]] = [[] for _ in lanes]
        n = 0
        for fno, by_lane in iter_lane_detections(_source(clip, frames), lanes, config,
                                                 start=clip.holdout_start - 1,
                                                 frames=clip.frames - clip.holdout_start + 1):
            n += 1
            for table, dets in zip(tables, by_lane):
                table.append(dets.with_frames(np.full(len(dets), fno, np.int64)))
        secs = time.perf_counter() - t0
        gt = _gt(pics)
        keyframes = np.array([p.frame for p in pics], np.int64)
        # each frame's counts, for the standard error over the frames
        return {k: frame_counts(gt, _predictions(table), keyframes) for k, table in zip(lanes, tables)}, secs, n

    return run


def _warm_up(video: str) -> None:
    """A few frames through the video pipeline: its models and kernels loaded before the
    timed runs."""
    from ..video.run import detect_video

    for _ in detect_video(video, frames=2):
        pass


def own_window_boxes(model: Model, horizon: float | None) -> Callable[[np.ndarray], np.ndarray]:
    """A frame ``(H, W, 3) uint8 BGR`` of the camera -> the boxes ``(N, 4) int32`` the video
    pipeline's window boxes give with ``model`` (:func:`fastdet.video.nmsboxes.nms_boxes`): its
    positive windows at the video search's bands placed at ``horizon`` (the camera's,
    :func:`~fastdet.video.run.file_horizon`), after non-maximum suppression; no tracker, no
    refinement. What the camera's box regressor learns from besides the jittered boxes
    (:func:`fastdet.train.adapt.fit_camera_regressor`)."""
    from ..detect import Detector
    from ..video.nmsboxes import nms_boxes

    detector = Detector(model, PipelineConfig().search)
    detector.set_horizon(horizon)

    def boxes(frame: np.ndarray) -> np.ndarray:
        return nms_boxes(detector.detect(frame)).boxes

    return boxes


def _after(model: Model, chosen: float, boxes: Boxes, footage: _adapt.Footage, run: _op.HoldoutRun,
           folder: Path) -> dict[str, Any]:
    """The agreement of the model moved by the chosen offset, recording the chosen box formation,
    from a run of the video pipeline with it (its time a frame is what ``video`` takes with the
    model written)."""
    path = folder / f"offset{chosen:+.3f}.npz"
    offset(model, chosen, metadata={BOXES_KEY: boxes}).save(path)
    try:
        return _op.agreement(footage, run, str(path)).to_dict()
    finally:
        path.unlink(missing_ok=True)


def _kept(frames: Mapping[str, HeldFrames], seconds: float) -> dict[str, Any]:
    """The summary's ``kept_aside``: the frames held in memory and in files, the seconds of
    that one reading (decoding up to each stretch included) and its decoding ms a frame (the
    runs' ms a frame no longer holds it)."""
    held = list(frames.values())
    n = sum(len(f) for f in held)
    return {"frames_in_memory": sum(len(f) for f in held if f.spill is None),
            "frames_in_files": sum(len(f) for f in held if f.spill is not None),
            "read_seconds": round(seconds, 2),
            "decode_ms_per_frame": round(1000.0 * sum(float(f.decode_seconds.sum()) for f in held) / n, 2)
            if n else None}


def _fmt(a: dict[str, Any] | None) -> str:
    if a is None:
        return "not measured"

    def n(v: float | None) -> str:
        return "-" if v is None else f"{v:.2f}"

    return (f"F1 {n(a['f1'])} (P {n(a['precision'])}, R {n(a['recall'])}; {a['tp']} hits, {a['fp']} false, "
            f"{a['fn']} missed), {n(a['ms_per_frame'])} ms a frame")


def _finite(v: float) -> float | None:
    """``v``, or ``None`` for +inf (the side-view component left out), for the JSON summary."""
    return None if v == math.inf else v


def side_line(summary: Mapping[str, Any]) -> str:
    """The summary's line on the side-view component."""
    fit = summary["fit"]
    if "positives" not in fit:
        return f"side-view component: none ({fit['skipped']})"
    head = (f"side-view component: fitted on {fit['vehicles']} vehicles ({fit['positives']} positive, "
            f"{fit['negatives']} background, {fit['hard_negatives']} hard negative crops)")
    if "offsets_f1" not in summary:
        return head + "; left out (no window boxes to join)"

    def f1(v: float | None) -> str:
        return "-" if v is None else f"{v:.2f}"

    tried = ", ".join(f"{'left out' if k == 'inf' else k} {f1(v)}" for k, v in summary["offsets_f1"].items())
    got = "left out" if summary["offset"] is None else f"offset {summary['offset']:g}"
    return head + f"; with window boxes, offsets tried (F1): {tried}; chosen: {got}"


def _cluster_labelling(args: argparse.Namespace) -> Callable[[float], _adapt.Labeller] | None:
    """With ``--workers`` or ``--scheduler``: what makes the labeller that runs the teacher on the
    Dask cluster (given the teacher's score floor); checked here, before any long work: Dask
    installed, a scheduler address of the right form, not both options, a teacher to run."""
    scheduler = args.scheduler
    if args.workers is None and not scheduler:
        return None
    if scheduler and args.workers:
        raise FastdetError("--workers is for a local cluster; with --scheduler the cluster's workers label the videos")
    if args.teacher is None:
        raise FastdetError("--workers / --scheduler run the teacher on a cluster: they need --teacher")
    try:
        from ..batch import labelling
        from ..batch.cluster import check_address
    except ImportError as exc:
        if (exc.name or "").split(".")[0] in ("dask", "distributed"):
            raise FastdetError(f"labelling on a cluster runs on Dask, which is not installed ({exc.name}): "
                               f"pip install fastdet[cluster]") from None
        raise
    if scheduler:
        check_address(scheduler)
    teacher, size, workers = os.path.abspath(args.teacher), args.teacher_size, args.workers

    def make(min_score: float) -> _adapt.Labeller:
        def label(clips: Sequence[_adapt.Clip], footage: _adapt.Footage
                  ) -> Iterator[tuple[_adapt.Clip, list[Any]]]:
            tasks = {labelling.LabelTask(os.path.abspath(c.path), tuple(footage.planned(c)),
                                         teacher, size, min_score): c for c in clips}
            if tasks:
                print(f"labelling {len(tasks)} video{'s' if len(tasks) != 1 else ''} on the "
                      f"{'cluster at ' + scheduler if scheduler else 'local Dask cluster'}", flush=True)
            for task, labelled in labelling.label_on_cluster(list(tasks), workers, scheduler):
                yield tasks[task], labelled

        return label

    return make


#: the camera's horizon from its labelled vehicles is tried only this far (a fraction of the frame
#: height) from the flow's: nearer, the bands would barely move
HORIZON_GAP = 0.05


def choose_horizon(model: Model, footage: _adapt.Footage, pictures: Sequence[AnnotatedPicture],
                   held: dict[str, list[AnnotatedPicture]], horizons: dict[str, float | None],
                   config: AdaptConfig, work: Path, progress: bool,
                   frames: Mapping[str, HeldFrames] | None = None) -> tuple[dict[str, Any], float | None]:
    """The camera's horizon: the one its labelled vehicles' boxes imply
    (:func:`~fastdet.video.horizon.horizon_from_boxes` over ``pictures``' frames of the footage's
    videos, the kept-aside ones too: a short footage's training frames hold too few vehicles for a
    line; stills and other videos' frames are other cameras) or the ones the flow gives
    (``horizons``: :func:`~fastdet.video.run.file_horizon` of each video, what a ``video`` run
    estimates). The kept-aside frames are replayed with ``model`` at the flow's horizons and at the
    vehicles' one (:func:`~fastdet.train.operating_point.choose_operating_point`: every formation
    and offset), and the vehicles' horizon is kept only when the best F1 of the formation chosen
    there is above the flow's by more than its standard error: the flow's is the default, as a
    ``video`` run has it. Tried only when it is at least :data:`HORIZON_GAP` of the height from
    some video's flow horizon and frames were kept aside. ``frames``: the stretches held
    (:func:`held_stretches`, read once for this and the operating point); ``None``: read here.
    Returns the summary's ``horizon`` entry (``flow``: the first video's) and the horizon to record
    (``None``: the flow's)."""
    flow = horizons[footage.clips[0].name]
    height = footage.size[1]
    videos = {os.path.realpath(c.path) for c in footage.clips}
    boxes = [p.targets for p in pictures
             if len(p.targets) and p.frame is not None and os.path.realpath(p.path) in videos]
    from_boxes = horizon_from_boxes(np.concatenate(boxes), height) if boxes else None
    summary: dict[str, Any] = {"flow": flow, "boxes": from_boxes, "chosen": "flow"}
    if from_boxes is None:
        summary["skipped"] = (f"fewer than {MIN_BOXES} labelled vehicles with their bottom edge in the frame, "
                              f"or no line through them")
    elif all(abs(from_boxes - (REFERENCE_HORIZON if f is None else f)) < HORIZON_GAP for f in horizons.values()):
        summary["skipped"] = f"within {HORIZON_GAP:g} of the height of the flow's"
    elif not any(held.values()):
        summary["skipped"] = "no labelled frame kept aside to choose it on"
    if "skipped" in summary:
        return summary, None
    assert from_boxes is not None
    folder = work / "horizon"
    results: dict[str, tuple[float, float]] = {}
    with held_stretches(footage, held, config, folder) if frames is None else nullcontext(frames) as held_frames:
        for name, at in (("flow", horizons), ("boxes", dict.fromkeys(horizons, from_boxes))):
            formation, _, by_boxes = _op.choose_operating_point(
                model, footage, holdout_lanes(held, held_frames, at), folder, config.offsets, BOXES, progress,
                seed=config.seed)
            c = by_boxes[formation]
            results[name] = (c.results[c.best].to_dict()["f1"] or 0.0, c.se)
    shutil.rmtree(folder, ignore_errors=True)
    summary["f1"] = {k: round(v[0], 4) for k, v in results.items()}
    summary["f1_se"] = round(results["boxes"][1], 4)
    if results["boxes"][0] - results["boxes"][1] > results["flow"][0]:
        summary["chosen"] = "boxes"
        return summary, from_boxes
    return summary, None


def horizon_line(summary: Mapping[str, Any]) -> str:
    """The printout's line of the camera's horizon choice (the summary's ``horizon`` entry)."""
    def at(v: float | None) -> str:
        return "the reference" if v is None else f"{v:.3f}"

    flow, boxes = summary["flow"], summary["boxes"]
    head = f"horizon: the flow's {at(flow)}, the labelled vehicles' " + ("none" if boxes is None else at(boxes))
    if "skipped" in summary:
        return f"{head}; kept the flow's ({summary['skipped']})"
    f1 = summary["f1"]
    return (f"{head}; F1 on the kept-aside frames {f1['flow']:.2f} / {f1['boxes']:.2f} (+- {summary['f1_se']:.2f}); "
            + ("chosen: the labelled vehicles'" if summary["chosen"] == "boxes" else "chosen: the flow's"))


@dataclass(frozen=True)
class OperatingPoint:
    """What ``adapt`` chose on the kept-aside frames: the model to write (with the side-view
    component and its offset when kept), its box formation and decision offset, and what the
    summary records of the choice (each field as the summary's entry of the same name)."""

    model: Model
    boxes: Boxes
    offset: float
    offsets_f1: dict[str, Any]  # F1 of each offset tried, with the formation kept
    formations: dict[str, Any]  # the summary's ``boxes_tried``
    side: dict[str, Any]
    kept: dict[str, Any]
    before: dict[str, Any] | None  # agreement of the bundled model
    after: dict[str, Any] | None  # agreement of the model written


def operating_point(model: Model, side: Model | None, side_fit: dict[str, Any], footage: _adapt.Footage,
                    held: dict[str, list[AnnotatedPicture]], horizons: dict[str, float | None],
                    flow_horizons: dict[str, float | None], config: AdaptConfig, work: Path,
                    progress: bool, frames: tuple[Mapping[str, HeldFrames], float] | None = None) -> OperatingPoint:
    """The box formation, the decision offset and the side-view component's offset (or none),
    chosen by replaying the kept-aside frames (``held``) at the camera's ``horizons``; with no
    labelled frame kept aside the model keeps its own operating point (heat map, offset 0) and no
    component. The bundled model's agreement (``before``) is that of a ``video`` run, at the
    flow's horizons. ``frames``: the stretches held (:func:`held_stretches`) and the seconds their
    reading took; ``None``: read here."""
    n_held = sum(len(v) for v in held.values())
    before = after = None
    chosen = 0.0
    boxes: Boxes = "heat"
    tried: dict[str, Any] = {}
    formations: dict[str, Any] = {}
    kept: dict[str, Any] = {}
    side_summary: dict[str, Any] = {"fit": side_fit, "offset": None}
    if not n_held:
        return OperatingPoint(model, boxes, chosen, tried, formations, side_summary, kept, before, after)
    _warm_up(footage.clips[0].path)
    with nullcontext(frames) if frames is not None else _read_held(footage, held, config,
                                                                  work / "operating-point") as (held_frames, secs):
        kept = _kept(held_frames, secs)
        run_holdout = holdout_run(held, held_frames, horizons)
        before = _op.agreement(footage, holdout_run(held, held_frames, flow_horizons), None).to_dict()
        boxes, chosen, by_boxes = _op.choose_operating_point(
            model, footage, holdout_lanes(held, held_frames, horizons), work / "operating-point", config.offsets, BOXES,
            progress, seed=config.seed)
        formations = {b: {"offset": c.offset, "f1": c.results[c.offset].to_dict()["f1"], "best_offset": c.best,
                          "best_f1": c.results[c.best].to_dict()["f1"], "f1_se": round(c.se, 4)}
                      for b, c in by_boxes.items()}
        r = by_boxes[boxes].results[chosen]
        if side is not None and "nms" in by_boxes:
            sc = _op.choose_side_offset(replace(model, side=side), footage, holdout_lanes(held, held_frames, horizons),
                                        work / "operating-point", "nms", by_boxes["nms"].offset,
                                        config.side_offsets, progress, seed=config.seed)
            side_summary.update({"offsets_f1": {f"{o:g}": a.to_dict()["f1"] for o, a in sc.results.items()},
                                 "best_offset": _finite(sc.best), "f1_se": round(sc.se, 4)})
            if _op.use_side(boxes, by_boxes, sc):
                if boxes != "nms":
                    side_summary["instead_of"] = boxes  # the formation chosen without it
                boxes, chosen = "nms", by_boxes["nms"].offset
                model = side_offset(replace(model, side=side), sc.offset)
                side_summary["offset"] = sc.offset
                r = sc.results[sc.offset]
        tried = {f"{o:g}": a.to_dict()["f1"] for o, a in by_boxes[boxes].results.items()}  # the formation kept
        after = _after(model, chosen, boxes, footage, run_holdout, work / "operating-point")
    if (after["tp"], after["fp"], after["fn"]) != (r.tp, r.fp, r.fn):
        print(f"note: at offset {chosen:g} the pipeline run found {after['tp']} / {after['fp']} / {after['fn']} "
              f"(hits / false / missed), the replay of the offsets {r.tp} / {r.fp} / {r.fn}", flush=True)
    return OperatingPoint(model, boxes, chosen, tried, formations, side_summary, kept, before, after)


def print_report(summary: Mapping[str, Any], secs: Mapping[str, float], own_regressor: bool, out: Path,
                 work: Path) -> None:
    """The lines ``adapt`` ends with, read from the ``summary`` it writes into the model file
    (``secs``: the seconds of each step, unrounded; ``own_regressor``: the camera's box regressor
    was fitted)."""
    frames, counts, fit = summary["frames"], summary["crops"], summary["regressor_fit"]
    labelled_by, n_held = summary["labelled_by"], frames["kept_aside_labelled"]
    print(f"frames: {frames['trained']} trained on ({summary['targets_trained']} {labelled_by} targets; "
          f"{counts['positives']} positive, {counts['negatives']} background, {counts['hard_negatives']} hard "
          f"negative crops x weight {summary['config']['weight']}), {n_held} kept-aside frames scored")
    if own_regressor:
        print(f"box regressor: fitted on {fit['samples']} boxes about {fit['groups']} "
              f"labelled vehicles (jittered, and {fit['own_boxes']} of the model's own x "
              f"{summary['config']['own_box_weight']}); a box's IoU with its vehicle {fit['input_mean_iou']:.2f} -> "
              f"{fit['output_mean_iou']:.2f} after one step (mean, cross-validated)")
    else:
        print(f"box regressor: the bundled one (only {fit['groups']} labelled vehicles to fit the "
              f"camera's own on, fewer than {_adapt.MIN_REGRESSOR_VEHICLES})")
    print("seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in secs.items()))
    print(horizon_line(summary["horizon"]))
    if n_held:
        def f1(v: float | None) -> str:
            return "-" if v is None else f"{v:.2f}"

        formations, boxes, side_summary = summary["boxes_tried"], summary["boxes"], summary["side"]
        print("boxes tried (F1 at their best offset): "
              + ", ".join(f"{b} {f1(v['best_f1'])} (offset {v['best_offset']:g})" for b, v in formations.items())
              + f"; chosen {boxes}"
              + (f" (with the side-view component, instead of {side_summary['instead_of']})"
                 if "instead_of" in side_summary else ""))
        fb = formations[boxes]
        print(f"offsets tried with {boxes} boxes (F1): "
              + ", ".join(f"{k} {f1(v)}" for k, v in summary["offsets_f1"].items())
              + f"; best {fb['best_offset']:g} (F1 {f1(fb['best_f1'])} +- {fb['f1_se']:.2f} over the kept-aside "
              f"frames); chosen {summary['offset']:g} by the one-standard-error rule")
        print(side_line(side_summary))
    else:
        print("no labelled frame kept aside: the model keeps its own operating point (offset 0) and fits no "
              "side-view component")
    print(f"agreement with the {labelled_by} labels on the kept-aside frames:")
    print(f"  before (bundled model): {_fmt(summary['agreement']['before'])}")
    print(f"  after  ({out.name}): {_fmt(summary['agreement']['after'])}")
    print(f"wrote {out} (its metadata['adapt'] holds this summary; labels kept in {work})", flush=True)


def run(args: argparse.Namespace) -> int:
    """The ``adapt`` subcommand."""
    t_start = time.perf_counter()
    progress = not args.no_progress and sys.stderr.isatty()
    config = _config(args)
    out: Path = args.output
    if (args.teacher is None) == (args.frames is None):
        raise FastdetError("give --teacher MODEL.onnx (a CNN labels the footage) or --frames SPEC (your own "
                           "labels), one of them")
    cluster = _cluster_labelling(args)
    videos: list[str] = []
    for f in args.footage:
        videos += video_files(f)
    _check_output(out, [("FOOTAGE", v) for v in videos] + [("--teacher", args.teacher)])
    data = Path(args.data or data_dir())
    _check_data(data)
    footage = _adapt.plan_footage(videos, config)
    detector = user_pictures = None
    if args.teacher is not None:
        from ..teacher.yolox import TeacherDetector

        detector = TeacherDetector(args.teacher, size=args.teacher_size, threads=args.threads)
    else:
        from ..labels.sets import read_spec

        user_pictures = read_spec(args.frames)
    bundled = load_model()
    work = work_folder(out)
    try:
        work.mkdir(exist_ok=True)
    except OSError as exc:
        raise DataError(f"{work}: cannot make the work folder ({exc.strerror or exc})") from None
    _numba.ensure_compiled(_numba.all_kernels(), what="the kernels")
    w, h = footage.size
    print(f"{len(footage.clips)} video{'s' if len(footage.clips) != 1 else ''} of {w}x{h}: "
          f"{sum(c.frames for c in footage.clips)} frames; sampling 1 frame in {footage.step} "
          f"({footage.n_train} frames to train on), {footage.holdout_length} frames kept aside "
          f"({footage.n_holdout} labelled)", flush=True)

    secs: dict[str, float] = {}
    t = time.perf_counter()
    if detector is not None:
        folder = work / _adapt.label_key(args.teacher, args.teacher_size, detector.config.min_score)
        labeller = None if cluster is None else cluster(detector.config.min_score)
        labels, n_now = _adapt.label_clips(footage, detector, folder, progress, labeller=labeller)
        pictures = _adapt.teacher_pictures(footage, labels, config.min_score)
        labelled_by = "teacher"
    else:
        assert user_pictures is not None
        pictures, n_now, labelled_by = user_pictures, 0, "user"
    secs["label"] = time.perf_counter() - t
    train_pics, held = _adapt.split_pictures(footage, pictures)
    n_targets = sum(len(p.targets) for p in train_pics)
    if not n_targets:
        raise DataError(f"no vehicle labelled on the {len(train_pics)} frames to train on: nothing to adapt to")

    crops, counts, crop_secs = _adapt.camera_crops(train_pics, bundled, config, progress)
    secs.update(crop_secs)
    model, fit_secs = _adapt.fit_mined_camera_model(data, bundled, train_pics, crops, counts, config, progress,
                                                   log=lambda s: print(s, flush=True))
    secs["hard_negatives"] += fit_secs["hard_negatives"]
    secs["train"] = fit_secs["train"]
    # every model file written from here on runs without the bundled oncoming model: the camera's
    # own model finds that traffic (docs/training.md, "The oncoming model beside an adapted model")
    model = replace(model, metadata={**model.metadata, ONCOMING_KEY: False})
    _signals.check()
    t = time.perf_counter()
    # the camera's horizon, as a `video` run of each file has it (the flow's), or the one its labelled
    # vehicles imply where the kept-aside frames say so: the regressor's own boxes, the side-view
    # component's negatives and the kept-aside runs search there, not at one read from a stretch's own
    # first frames
    flow_horizons = {c.name: file_horizon(c.path) for c in footage.clips
                     if c is footage.clips[0] or held.get(c.name)}
    # each kept-aside stretch read once, for the horizon's replays and the operating point's (held in
    # memory, or in files, through the two fits between them)
    with _read_held(footage, held, config, work / "operating-point") as (frames, read_secs):
        horizon_summary, camera_hz = choose_horizon(model, footage, pictures, held, flow_horizons, config, work,
                                                    progress, frames=frames)
        horizons = flow_horizons if camera_hz is None else dict.fromkeys(flow_horizons, camera_hz)
        secs["horizon"] = time.perf_counter() - t - read_secs  # the reading: the operating point's, as it reads them
        _signals.check()
        t = time.perf_counter()
        regressor, regressor_fit = _adapt.fit_camera_regressor(
            train_pics, load_regressor(), config, progress,
            own_boxes=own_window_boxes(model, horizons[footage.clips[0].name]))
        if regressor is not None:
            model = carrying(model, regressor)  # every model file written from here on carries it
        secs["regressor"] = time.perf_counter() - t
        _signals.check()
        t = time.perf_counter()
        side: Model | None = None
        side_fit: dict[str, Any] = {"skipped": "no labelled frame kept aside to choose it on"}
        if any(held.values()):
            side, side_fit = _side.fit_side_model(
                train_pics, model, replace(PipelineConfig().search, horizon=horizons[footage.clips[0].name]), config,
                progress)
        secs["side"] = time.perf_counter() - t
        _signals.check()

        t = time.perf_counter()
        n_held = sum(len(v) for v in held.values())
        op = operating_point(model, side, side_fit, footage, held, horizons, flow_horizons, config, work, progress,
                             frames=(frames, read_secs))
        model = op.model
        secs["operating_point"] = time.perf_counter() - t + read_secs
    secs["total"] = time.perf_counter() - t_start
    _signals.check()

    summary: dict[str, Any] = {
        "command": "python -m fastdet adapt " + " ".join(sys.argv[2:]),
        "footage": [{"video": os.path.abspath(c.path), "frames": c.frames, "kept_aside_from": c.holdout_start}
                    for c in footage.clips],
        "frame_size": [w, h], "labelled_by": labelled_by, "horizons": flow_horizons, "horizon": horizon_summary,
        "teacher": None if args.teacher is None else {"model": os.path.abspath(args.teacher),
                                                      "size": args.teacher_size},
        "frames": {"step": footage.step, "trained": len(train_pics), "kept_aside_labelled": n_held,
                   "kept_aside_read": footage.holdout_length, "labelled_now": n_now},
        "targets_trained": n_targets, "crops": counts, "regressor_fit": regressor_fit,
        "seconds": {k: round(v, 2) for k, v in secs.items()},
        "offset": op.offset, "offsets_f1": op.offsets_f1, "boxes": op.boxes, "boxes_tried": op.formations,
        "side": op.side, "kept_aside": op.kept,
        "agreement": {"before": op.before, "after": op.after},
        "config": config.to_dict(),
    }
    records: dict[str, Any] = {"adapt": summary, BOXES_KEY: op.boxes}
    if camera_hz is not None:
        records[HORIZON_KEY] = camera_hz
    final = offset(model, op.offset, metadata=records)
    final.save(out)
    shutil.rmtree(work / "operating-point", ignore_errors=True)
    print_report(summary, secs, regressor is not None, out, work)
    return 0

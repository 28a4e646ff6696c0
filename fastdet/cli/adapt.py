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
  Each kept-aside stretch is decoded once for the runs over it (:func:`~fastdet.cli.kept_aside.held_stretches`:
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
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from .. import _numba
from .. import signals as _signals
from ..config import PipelineConfig
from ..config.adapt import AdaptConfig
from ..data import data_dir
from ..detect.regressor import carrying, load_regressor
from ..errors import DataError, FastdetError
from ..io.files import not_found
from ..io.paths import check_paths, is_inside
from ..model import Model, load_model
from ..train import adapt as _adapt
from ..train import side as _side
from ..train.blend import offset
from ..video.detector import BOXES_KEY, HORIZON_KEY, ONCOMING_KEY
from ..video.run import file_horizon
from ._args import fraction, positive_int, teacher_size, video_files
from .kept_aside import choose_horizon, operating_point, read_held

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


def _fmt(a: dict[str, Any] | None) -> str:
    if a is None:
        return "not measured"

    def n(v: float | None) -> str:
        return "-" if v is None else f"{v:.2f}"

    return (f"F1 {n(a['f1'])} (P {n(a['precision'])}, R {n(a['recall'])}; {a['tp']} hits, {a['fp']} false, "
            f"{a['fn']} missed), {n(a['ms_per_frame'])} ms a frame")


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
    with read_held(footage, held, config, work / "operating-point") as (frames, read_secs):
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
                             frames, read_secs)
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

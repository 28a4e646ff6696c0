"""``adapt``'s kept-aside frames: each clip's stretch read once and held, the video pipeline
replayed over it, and the choices made there -- the camera's horizon (:func:`choose_horizon`) and
the operating point (:func:`operating_point`: the box formation, the decision offset, the
side-view component's offset) -- with the agreement before and after.

The last ``--holdout`` fraction of each video is kept aside (:func:`fastdet.train.adapt.split_pictures`);
its labelled frames score each run (:func:`fastdet.eval.evaluate`, IoU 0.5). The stretches are
decoded once (:func:`held_stretches`: in memory up to ``AdaptConfig.hold_bytes``, the rest in raw
files in the work folder) for every run over them.
"""
from __future__ import annotations

import math
import os
import shutil
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..config import BOXES, REFERENCE_HORIZON, Boxes, PipelineConfig
from ..config.adapt import AdaptConfig
from ..detections import Detections
from ..errors import WriteError
from ..io.held import HeldFrames
from ..io.hold import hold_frames
from ..labels.picture import AnnotatedPicture
from ..model import Model
from ..train import adapt as _adapt
from ..train import operating_point as _op
from ..train.blend import offset, side_offset
from ..video.detector import BOXES_KEY
from ..video.horizon import MIN_BOXES, horizon_from_boxes


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
    held for the horizon's and the operating point's runs (:func:`fastdet.io.hold.hold_frames`), ``{clip name:
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
def read_held(footage: _adapt.Footage, held: Mapping[str, list[AnnotatedPicture]], config: AdaptConfig,
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


def _finite(v: float) -> float | None:
    """``v``, or ``None`` for +inf (the side-view component left out), for the JSON summary."""
    return None if v == math.inf else v


#: the camera's horizon from its labelled vehicles is tried only this far (a fraction of the frame
#: height) from the flow's: nearer, the bands would barely move
HORIZON_GAP = 0.05


def choose_horizon(model: Model, footage: _adapt.Footage, pictures: Sequence[AnnotatedPicture],
                   held: dict[str, list[AnnotatedPicture]], horizons: dict[str, float | None],
                   config: AdaptConfig, work: Path, progress: bool,
                   frames: Mapping[str, HeldFrames]) -> tuple[dict[str, Any], float | None]:
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
    (:func:`held_stretches`, read once for this and the operating point).
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
    for name, at in (("flow", horizons), ("boxes", dict.fromkeys(horizons, from_boxes))):
        formation, _, by_boxes = _op.choose_operating_point(
            model, footage, holdout_lanes(held, frames, at), folder, config.offsets, BOXES, progress, seed=config.seed)
        c = by_boxes[formation]
        results[name] = (c.results[c.best].to_dict()["f1"] or 0.0, c.se)
    shutil.rmtree(folder, ignore_errors=True)
    summary["f1"] = {k: round(v[0], 4) for k, v in results.items()}
    summary["f1_se"] = round(results["boxes"][1], 4)
    if results["boxes"][0] - results["boxes"][1] > results["flow"][0]:
        summary["chosen"] = "boxes"
        return summary, from_boxes
    return summary, None


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
                    progress: bool, frames: Mapping[str, HeldFrames], read_seconds: float) -> OperatingPoint:
    """The box formation, the decision offset and the side-view component's offset (or none),
    chosen by replaying the kept-aside frames (``held``) at the camera's ``horizons``; with no
    labelled frame kept aside the model keeps its own operating point (heat map, offset 0) and no
    component. The bundled model's agreement (``before``) is that of a ``video`` run, at the
    flow's horizons. ``frames``: the stretches held (:func:`held_stretches`); ``read_seconds``: what
    their reading took."""
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
    kept = _kept(frames, read_seconds)
    run_holdout = holdout_run(held, frames, horizons)
    before = _op.agreement(footage, holdout_run(held, frames, flow_horizons), None).to_dict()
    boxes, chosen, by_boxes = _op.choose_operating_point(
        model, footage, holdout_lanes(held, frames, horizons), work / "operating-point", config.offsets, BOXES,
        progress, seed=config.seed)
    formations = {b: {"offset": c.offset, "f1": c.results[c.offset].to_dict()["f1"], "best_offset": c.best,
                      "best_f1": c.results[c.best].to_dict()["f1"], "f1_se": round(c.se, 4)}
                  for b, c in by_boxes.items()}
    r = by_boxes[boxes].results[chosen]
    if side is not None and "nms" in by_boxes:
        sc = _op.choose_side_offset(replace(model, side=side), footage, holdout_lanes(held, frames, horizons),
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

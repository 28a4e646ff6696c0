"""Learned box refinement (:mod:`fastdet.video.refine`), measured cross-clip on the real pipeline's boxes.

For each held-out clip E of ``$FASTDET_DATA`` (``test_small1``, ``test_video``), a box
regressor is fitted (:mod:`fastdet.train.refine`) on the annotated vehicles of the *other*
clip and the six test images (``tools/test_images.gt.txt``) -- never on E
(:mod:`tools.scripts.refine_model`, which builds the bundled regressor). The default video
pipeline (``VideoDetector``: main + oncoming model, heat maps, tracker, horizon primed from
the clip, as ``iter_video_detections``) runs on E (and on camera-shift variants of it,
``--variants``, :mod:`fastdet.eval.variants`), each frame's boxes are refined, and both are
scored with :func:`fastdet.eval.evaluate` at IoU 0.5 (F1, AP, IDF1, FP per frame) and by the
IoU of *paired* boxes: each vehicle (``consider = 1``) paired with the pipeline box that
overlaps it most if that IoU >= 0.3 (greedy, one box per vehicle), the IoU of the same box
with the same vehicle before and after refinement (median, fraction >= 0.5 and >= 0.7).

    python -m tools.studies.refine_eval [--clips test_small1,test_video] [--variants original,960x540,wide0.8]
        [--contexts 1.5] [--iterations 1] [--parts 0,1] [--per-box 16] [--hog-channels 0]
        [--cache DIR] [--json OUT.json] [--ship fastdet/models/refine.npz]
        [--model M.npz] [--oncoming-model W.npz]

``--ship PATH`` also fits one regressor on the clips ``--ship-clips`` names (default
``test_video``) and the six test images (:mod:`tools.scripts.refine_model`), and writes it to
PATH with this run's measurement in its metadata. The bundled
``fastdet/models/refine.npz`` is fitted that way, never on ``test_small1``: it is exactly the
regressor that ``--clips test_small1`` measures held out, and ``eval`` on ``test_small1``
stays a held-out figure (on ``test_video`` it is in-sample). Pipeline boxes are cached under ``--cache`` (default
``$TMPDIR/fastdet_refine_eval``), keyed by clip and variant, so settings of the refinement
can be compared without running the detector again. The pipeline runs with its own refinement
off (``PipelineConfig(refine=None)``): "before" is the unrefined boxes, as when the bundled
regressor was made (the refinement has been on by default since; before this was said, the
study's "before" was the boxes the bundled regressor had refined already). ``--model`` and
``--oncoming-model`` run it with other model files than the bundled ones; give a ``--cache``
of its own then (and after a change of the pipeline): the cache is keyed by clip and variant only.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from fastdet.config import PipelineConfig
from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval import evaluate
from fastdet.eval.variants import Variant, standard_variants, transform_gt
from fastdet.io.motfiles import read_gt
from fastdet.train.refine import paired_iou
from fastdet.video import VideoDetector, make_detector
from fastdet.video.refine import BoxRegressor, RefineConfig, refine
from tools.scripts.refine_model import (
    CLIPS,
    add_feature_arguments,
    check_clips,
    clip_vehicles,
    fit_box_regressor,
    samples,
    spec_of,
)
from tools.studies.frame_cache import load_frame_detections, save_frame_detections

from .camera_shift import read_frames, variant_frames


def clip_data(clip: str) -> tuple[list[np.ndarray], Detections]:
    root = data_dir()
    return read_frames(root / "videos" / f"{clip}.mp4"), read_gt(root / "annotations" / f"{clip}.gt.txt")


# ---------------------------------------------------------------------------------------- pipeline boxes


def _part_of(boxes: np.ndarray, windows: Detections) -> np.ndarray:
    """``(N,) int8``: 1 where most positive windows centred in a box are the wide model's."""
    out = np.zeros(len(boxes), np.int8)
    if len(windows) == 0 or len(boxes) == 0:
        return out
    wb = windows.boxes.astype(np.float64)
    cx, cy = 0.5 * (wb[:, 0] + wb[:, 2]), 0.5 * (wb[:, 1] + wb[:, 3])
    wide = windows.is_oncoming
    for i, b in enumerate(boxes):
        inside = (cx >= b[0]) & (cx < b[2]) & (cy >= b[1]) & (cy < b[3])
        out[i] = int(inside.any() and wide[inside].sum() > (~wide[inside]).sum())
    return out


def pipeline_boxes(det: Any, frames: list[np.ndarray], cache: Path,
                   config: PipelineConfig | None = None) -> list[Detections]:
    """The pipeline's boxes of every frame before any refinement (cached in ``cache``), ``part``
    filled by :func:`_part_of` (the tracker's output has no part column); ``config`` (default
    ``PipelineConfig()``) names its model files; its refinement is turned off."""
    if cache.exists():
        return load_frame_detections(cache)
    vd = VideoDetector(det, replace(config if config is not None else PipelineConfig(horizon="auto"), refine=None))
    vd.prime_horizon(frames)
    vd.warmup()
    out = []
    for f in frames:
        d = vd.update(f)
        ids = d.ids if d.ids is not None else np.full(len(d), -1)
        out.append(Detections(d.boxes, d.scores, part=_part_of(d.boxes, vd.debug.windows), ids=ids))
    save_frame_detections(cache, out)
    return out


# ---------------------------------------------------------------------------------------- scoring


def paired(gt: Detections, dets: list[Detections], min_iou: float = 0.3) -> list[tuple[int, int, int]]:
    """``(frame index, box row, gt row)``: each vehicle with the box overlapping it most
    (IoU >= ``min_iou``), greedily by IoU, one box per vehicle and one vehicle per box."""
    from fastdet.boxes import iou

    out = []
    for fi, d in enumerate(dets):
        rows = np.flatnonzero((gt.frames == fi + 1) & gt.consider)
        if not len(rows) or not len(d):
            continue
        m = iou(d.boxes, gt.boxes[rows])
        while True:
            i, j = np.unravel_index(int(np.argmax(m)), m.shape)
            if m[i, j] < min_iou:
                break
            out.append((fi, int(i), int(rows[j])))
            m[i, :] = -1
            m[:, j] = -1
    return out


def score(gt: Detections, dets: list[Detections], pairs: list[tuple[int, int, int]], n_frames: int) -> dict[str, Any]:
    preds = Detections.from_frames([(i + 1, d) for i, d in enumerate(dets)])
    r = evaluate(gt, preds, iou=0.5, num_frames=n_frames)
    ious = np.array([paired_iou(dets[fi].boxes[i:i + 1], gt.boxes[g:g + 1])[0] for fi, i, g in pairs])
    nan = math.nan
    return {"f1": r.f1, "ap": r.ap, "idf1": r.idf1, "fp_per_frame": r.fp_per_frame, "tp": r.tp, "fp": r.fp,
            "fn": r.fn, "pairs": len(ious),
            "iou_median": float(np.median(ious)) if len(ious) else nan,
            "iou_mean": float(np.mean(ious)) if len(ious) else nan,
            "iou_ge_0.5": float(np.mean(ious >= 0.5)) if len(ious) else nan,
            "iou_ge_0.7": float(np.mean(ious >= 0.7)) if len(ious) else nan}


def refine_all(frames: list[np.ndarray], dets: list[Detections], reg: BoxRegressor,
               cfg: RefineConfig) -> tuple[list[Detections], float]:
    """Every frame's boxes refined, and the milliseconds per frame it took."""
    refine(frames[0], dets[0], reg, cfg)  # warm the kernels
    t0 = time.perf_counter()
    out = [refine(f, d, reg, cfg) for f, d in zip(frames, dets)]
    return out, 1000 * (time.perf_counter() - t0) / len(frames)


# ---------------------------------------------------------------------------------------- main


def _fmt(row: dict[str, Any]) -> str:
    def g(k: str, d: int = 3) -> str:
        v = row[k]
        return "n/a" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{d}f}"
    return (f"F1 {g('f1')}  AP {g('ap')}  IDF1 {g('idf1')}  FP/frame {g('fp_per_frame')}  "
            f"TP/FP/FN {row['tp']}/{row['fp']}/{row['fn']}  pairs {row['pairs']}  IoU median {g('iou_median')} "
            f"mean {g('iou_mean')}  >=0.5 {g('iou_ge_0.5')}  >=0.7 {g('iou_ge_0.7')}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", default=",".join(CLIPS))
    ap.add_argument("--variants", default="original")
    ap.add_argument("--iterations", type=int, default=1)
    ap.add_argument("--parts", default=None, help="refine only these parts (0 main, 1 oncoming), e.g. 1")
    add_feature_arguments(ap)
    ap.add_argument("--cache", default=os.path.join(tempfile.gettempdir(), "fastdet_refine_eval"))
    ap.add_argument("--json", default=None)
    ap.add_argument("--ship", default=None,
                    help="also fit on --ship-clips + the test images and write the regressor here")
    ap.add_argument("--ship-clips", default="test_video",
                    help="clips the --ship regressor is fitted on, comma-separated (default: test_video, "
                         "so that test_small1 stays held out)")
    ap.add_argument("--model", default=None, help="the pipeline's main model file (default: the bundled one)")
    ap.add_argument("--oncoming-model", default=None,
                    help="the pipeline's oncoming-traffic model file (default: the bundled one)")
    a = ap.parse_args(argv)
    pipeline = PipelineConfig(horizon="auto", model=a.model, refine=None,
                              oncoming=a.oncoming_model if a.oncoming_model is not None else True)

    spec = spec_of(a)
    fcfg, contexts = spec.config, spec.contexts
    rcfg = RefineConfig(iterations=a.iterations,
                        parts=None if a.parts is None else tuple(int(p) for p in a.parts.split(",")))
    clips = [c for c in a.clips.split(",") if c]
    by_name = {v.name: v for v in standard_variants()}
    variants: list[Variant] = [by_name[n] for n in a.variants.split(",") if n]
    cache = Path(a.cache)

    data = {c: clip_data(c) for c in CLIPS}
    train_frames = {c: clip_vehicles(c, data[c]) for c in CLIPS}

    def samples_for(names: list[str]):
        return samples([fr for n in names for fr in train_frames[n]], spec, a.seed, a.per_box)

    det = make_detector(pipeline)
    rows: list[dict[str, Any]] = []
    settings = {"contexts": contexts, "features": fcfg.to_dict(), "iterations": a.iterations, "parts": a.parts,
                "per_box": a.per_box, "seed": a.seed}
    print(json.dumps(settings), flush=True)
    with tempfile.TemporaryDirectory(prefix="fastdet_refine_eval_") as tmpd:
        for clip in clips:
            others = [c for c in CLIPS if c != clip]
            t0 = time.perf_counter()
            smp = samples_for(others)
            reg = fit_box_regressor(smp, spec, metadata={"trained_on": others + ["test_images"]})
            fit = reg.metadata["fit"]
            print(f"[{clip}] regressor fitted on {'+'.join(others)}+test_images: {fit['samples']} samples of "
                  f"{fit['groups']} vehicles, alpha {fit['alpha']:g}, CV mean IoU {max(fit['cv_mean_iou']):.3f} "
                  f"(jittered {fit['jittered_mean_iou']:.3f}), {time.perf_counter() - t0:.1f} s", flush=True)
            src, gt0 = data[clip]
            for v in variants:
                frames = variant_frames(src, v, clip, Path(tmpd))
                gt = transform_gt(gt0, v, src[0].shape[:2])
                dets = pipeline_boxes(det, frames, cache / f"{clip}.{v.name}.npz", pipeline)
                pairs = paired(gt, dets)
                before = score(gt, dets, pairs, len(frames))
                refined, ms = refine_all(frames, dets, reg, rcfg)
                after = score(gt, refined, pairs, len(frames))
                nbox = sum(len(d) for d in dets) / len(frames)
                row = {"clip": clip, "variant": v.name, "before": before, "after": after, "ms_per_frame": ms,
                       "boxes_per_frame": nbox, "alpha": fit["alpha"]}
                rows.append(row)
                print(f"[{clip} {v.name}] before  {_fmt(before)}\n[{clip} {v.name}] after   {_fmt(after)}"
                      f"\n[{clip} {v.name}] refinement {ms:.2f} ms/frame ({nbox:.2f} boxes/frame)", flush=True)
    if a.ship:
        ship_clips = [c for c in a.ship_clips.split(",") if c]
        check_clips(ship_clips)
        smp = samples_for(ship_clips)
        reg = fit_box_regressor(smp, spec, metadata={
            "trained_on": ship_clips + ["test_images"], "settings": settings,
            "command": "python -m tools.studies.refine_eval " + " ".join(argv if argv is not None else sys.argv[1:]),
            "held_out": rows})
        reg.save(a.ship)
        print(f"wrote {a.ship}: fitted on {'+'.join(ship_clips)}+test_images, alpha {reg.metadata['fit']['alpha']:g}")
    if a.json:
        Path(a.json).write_text(json.dumps({"settings": settings, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

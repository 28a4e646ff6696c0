"""The small-vehicle component measured on every annotated clip (run by hand; docs/components.md,
"Small vehicles: a low-resolution model").

``--windows``: every window of the small search (moved to each clip's horizon as the pipeline
moves it) on the hand-read frames (keyframes; every 5th frame of a fully annotated clip), per
clip: the small targets (< 60 px wide of 1280), how many a window reaches at IoU >= 0.5, how many
of those have a window above each decision value of ``--levels``, the median best decision value,
and the false windows per frame above each level (IoU < 0.3 with every target and touching no
ignore region: ``fw``; touching no target either: ``clear``).

``--pipeline``: the video pipeline (``fastdet eval --all``'s) on every clip without and with the
component (``PipelineConfig(small=MODEL)``, ``--heat KEY=VALUE`` for its heat map), scored as
``eval --all`` scores (keyframes only, IoU 0.5): both markdown tables, and per clip the recall of
the small targets and the false alarms.

``--loo WORK``: the component with hard negatives mined on annotated frames
(:func:`fastdet.train.small.train_small` ``frames=``), left one camera out: for each fold of
:func:`tools.studies.loo.folds` a model mined on the other clips' annotated frames only
(``WORK/small_without_FOLD.npz``, kept when it exists; the data-set model of ``--model`` mines),
then the pipeline with it on the held-out clips, scored as ``--pipeline``.

``--peaks``: the pipeline with the component on every clip; on the hand-read frames, the peak of
the component's heat map inside each small target, and per frame the highest peak of a blob
touching no annotated box (the strongest false blob); the heat-threshold rule of docs/components.md reads
these.

``--cost``: what the component adds to a full scan of a 1280x720 frame at the reference horizon:
HOG cells (of the scaled bands), windows scored and the multiply-adds of scoring them (windows x
features per window), as ratios to the pipeline's search without it (main and oncoming models).
No clock: the machine is shared.

    python -m tools.studies.small_model [--model fastdet/models/small.npz] [--windows] [--pipeline]
        [--cost] [--loo WORK] [--clips A,B] [--heat threshold=3] [--threshold T] [--check D|off] [--no-refine]
        [--no-baseline] [--json OUT]
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from fastdet.boxes import intersection, iou
from fastdet.config import HeatConfig, PipelineConfig
from fastdet.config.models import SMALL_MODEL_PATH
from fastdet.data import data_dir
from fastdet.detect import Detector
from fastdet.detections import Detections
from fastdet.eval.clips import annotated_clips, markdown_table
from fastdet.eval.sizes import recall_by_width
from fastdet.io.reader import FrameReader, read_frames
from fastdet.model import Model, load_model
from fastdet.train.keyframes import AnnotatedFrame, read_annotated_frames
from fastdet.train.small import SmallRecipe, train_small
from fastdet.video import make_detector
from fastdet.video.horizon import HORIZON_FRAMES, estimate_horizon, search_horizon
from tools.studies.band_cost import scan_cost
from tools.studies.loo import folds, frame_rows, run_clip
from tools.studies.small_boxes import overrides, searched_windows

#: targets narrower than this (pixels of a 720-row frame) are "small"
SMALL_WIDTH = 60.0
LEVELS = (0.0, 1.0, 2.0, 3.0, 4.0)


def clip_horizon(video: Path) -> float | None:
    """The horizon the pipeline searches ``video`` at (:func:`~fastdet.video.horizon.search_horizon`
    of the estimate from its first frames; ``None``: the reference)."""
    return search_horizon(estimate_horizon(read_frames(video, 0, HORIZON_FRAMES, notify=lambda _n: None)))


def window_stats(frames: list[AnnotatedFrame], windows: list[tuple[np.ndarray, np.ndarray]],
                 levels: tuple[float, ...] = LEVELS, small_width: float = SMALL_WIDTH) -> dict[str, Any]:
    """The ``--windows`` figures of one clip (module docstring) from its annotated ``frames`` and
    the ``(boxes, decision values)`` of every searched window of each."""
    best = []
    fw = dict.fromkeys(levels, 0)
    clear = dict.fromkeys(levels, 0)
    for f, (b, d) in zip(frames, windows):
        tg = f.targets
        f_ref = 720.0 / f.image.shape[0]
        if len(tg) and len(b):
            ov = iou(tg, b)
            small = (tg[:, 2] - tg[:, 0]) * f_ref < small_width
            for k in np.flatnonzero(small):
                m = ov[k] >= 0.5
                best.append(float(d[m].max()) if m.any() else -np.inf)
            far = ov.max(0) < 0.3
            untouched = ~(intersection(tg, b) > 0).any(0)
        else:
            if len(tg):
                best += [-np.inf] * int(((tg[:, 2] - tg[:, 0]) * f_ref < small_width).sum())
            far = np.ones(len(b), bool)
            untouched = far.copy()
        if len(f.ignores) and len(b):
            free = ~(intersection(b, f.ignores) > 0).any(1)
            far &= free
            untouched &= free
        for t in levels:
            fw[t] += int((far & (d > t)).sum())
            clear[t] += int((untouched & (d > t)).sum())
    bv = np.array(best)
    reach = bv[np.isfinite(bv)]
    n = max(len(frames), 1)
    return {"frames": len(frames), "small": len(bv), "reached": len(reach),
            "positive": {t: int((bv > t).sum()) for t in levels},
            "median_best": float(np.median(reach)) if len(reach) else None,
            "fw_per_frame": {t: fw[t] / n for t in levels}, "clear_per_frame": {t: clear[t] / n for t in levels},
            "windows_per_frame": sum(len(w[1]) for w in windows) / n}


def windows_study(model: Model, clips: list, data: Path, levels: tuple[float, ...] = LEVELS) -> dict[str, Any]:
    """:func:`window_stats` of every clip, the component's search at the clip's horizon."""
    out = {}
    search = PipelineConfig().small_search
    for clip in clips:
        frames = read_annotated_frames(data, clip.name)
        det = Detector(model, search=search, horizon=clip_horizon(clip.video))
        out[clip.name] = window_stats(frames, [searched_windows(det, f.image) for f in frames], levels)
    return out


def print_windows(res: dict[str, Any], levels: tuple[float, ...] = LEVELS) -> None:
    lv = " / ".join(f"{t:g}" for t in levels)
    print(f"| clip | small targets | reached (IoU >= 0.5) | positive above {lv} | median best | "
          f"false windows / frame above {lv} | of them touching no target |")
    print("|---|---|---|---|---|---|---|")
    for name, r in res.items():
        med = "-" if r["median_best"] is None else f"{r['median_best']:.2f}"
        pos = " / ".join(str(r["positive"][t]) for t in levels)
        fw = " / ".join(f"{r['fw_per_frame'][t]:.1f}" for t in levels)
        clear = " / ".join(f"{r['clear_per_frame'][t]:.1f}" for t in levels)
        print(f"| {name} | {r['small']} | {r['reached']} | {pos} | {med} | {fw} | {clear} |")


def small_recall(clip, preds: Detections) -> tuple[int, int]:
    """``(found, total)`` of the clip's targets under :data:`SMALL_WIDTH` reference pixels."""
    b = recall_by_width(clip.gt(), preds, frame_rows(clip), edges=(0.0, SMALL_WIDTH), keyframes=clip.keyframes(),
                        num_frames=None)
    return b[0].found, b[0].total


def pipeline_study(config: PipelineConfig, small: str, clips: list, baseline: bool = True) -> dict[str, Any]:
    """Every clip without (unless not ``baseline``) and with the component:
    ``{"without": [ClipScore], "with": [...], "rows": {...}}``."""
    out: dict[str, Any] = {"without": [], "with": [], "rows": {}}
    runs = (("without", config.without("small")),) if baseline else ()
    runs += (("with", replace(config, small=small)),)
    for clip in clips:
        row = {}
        for key, cfg in runs:
            keep: list[Detections] = []
            score = run_clip(clip, cfg, keep)
            out[key].append(score)
            r = score.result
            row[key] = {"f1": r.f1, "p": r.precision, "r": r.recall, "fa_per_frame": r.fp_per_frame,
                        "tp": r.tp, "fa": r.fp, "small": small_recall(clip, keep[0])}
            print(f"{clip.name} {key}: F1 {r.f1:.2f} (P {r.precision:.2f} R {r.recall:.2f}) "
                  f"FA/frame {r.fp_per_frame:.2f}, small {row[key]['small'][0]}/{row[key]['small'][1]}",
                  file=sys.stderr, flush=True)
        out["rows"][clip.name] = row
    return out


def loo_study(config: PipelineConfig, base: str, clips: list, data: Path, work: Path,
              baseline: bool = True) -> dict[str, Any]:
    """:func:`pipeline_study` with, for each clip, the model of its fold (module docstring)."""
    work.mkdir(parents=True, exist_ok=True)
    names = [c.name for c in clips]
    all_names = [c.name for c in annotated_clips(data)]
    out: dict[str, Any] = {"without": [], "with": [], "rows": {}, "models": {}}
    base_model = load_model(base)
    for fold in folds(all_names):
        held = [c for c in clips if c.name in fold.held_out]
        if not held:
            continue
        path = work / f"small_without_{fold.name}.npz"
        if not path.is_file():
            frames = [f for c in fold.train for f in read_annotated_frames(data, c)]
            model = train_small(data, SmallRecipe(), command=f"tools.studies.small_model --loo (without {fold.name})",
                                frames=frames, base=base_model, log=lambda m: print(m, file=sys.stderr))
            model.save(path)
        out["models"][fold.name] = str(path)
        res = pipeline_study(config, str(path), held, baseline)
        for key in ("without", "with"):
            out[key] += res[key]
        out["rows"].update(res["rows"])
    order = {n: i for i, n in enumerate(names)}
    for key in ("without", "with"):
        out[key].sort(key=lambda s: order[s.name])
    return out


def heat_peaks(clip, config: PipelineConfig, data: Path) -> dict[str, list[float]]:
    """The ``--peaks`` figures of one clip: ``{"small": [peak heat inside each small target],
    "false": [the highest peak of a blob touching no annotated box, per frame]}`` (the component's
    heat map after the frame's update, its blobs the connected cells with any heat)."""
    from fastdet.video.run import video_detector_for

    frames = {f.frame: f for f in read_annotated_frames(data, clip.name)}
    reader = FrameReader(str(clip.video), notify=lambda _n: None)
    out: dict[str, list[float]] = {"small": [], "false": []}
    try:
        vd = video_detector_for(reader, make_detector(config), config)
        stage = next(st for st in vd.stages if st.name == "small")
        for fno, frame, _ in reader:
            vd.update(frame)
            f = frames.get(fno)
            if f is None or stage.heatmap is None:
                continue
            hm = stage.heatmap
            heat = hm.heat
            boxed = np.zeros(heat.shape, bool)
            for b in hm.to_grid(f.boxes.astype(np.int64)):
                boxed[b[1]: b[3], b[0]: b[2]] = True
            labels, n = ndimage.label(heat > 0)
            touching = np.unique(labels[boxed & (labels > 0)])
            peaks = ndimage.maximum(heat, labels, np.arange(1, n + 1)) if n else []
            free = [float(p) for i, p in enumerate(np.atleast_1d(peaks), 1) if i not in set(touching.tolist())]
            out["false"].append(max(free, default=0.0))
            f_ref = 720.0 / frame.shape[0]
            for t, g in zip(f.targets, hm.to_grid(f.targets.astype(np.int64))):
                if (t[2] - t[0]) * f_ref < SMALL_WIDTH and g[2] > g[0] and g[3] > g[1]:
                    out["small"].append(float(heat[g[1]: g[3], g[0]: g[2]].max()))
    finally:
        reader.close()
    return out


def search_cost(config: PipelineConfig, small: str, shape: tuple[int, int] = (720, 1280)) -> dict[str, float]:
    """HOG cells, windows and scoring multiply-adds of a full scan of a frame of ``shape`` at the
    reference horizon, without and with the component, and their ratios."""
    a = scan_cost(make_detector(config.without("small")), shape)
    b = scan_cost(make_detector(replace(config, small=small)), shape)
    return {**{f"without_{k}": v for k, v in a.items()}, **{f"with_{k}": v for k, v in b.items()},
            **{f"ratio_{k}": b[k] / a[k] for k in a}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default=str(SMALL_MODEL_PATH), help="the small-vehicle component (default: bundled)")
    ap.add_argument("--windows", action="store_true")
    ap.add_argument("--pipeline", action="store_true")
    ap.add_argument("--cost", action="store_true")
    ap.add_argument("--peaks", action="store_true", help="heat peaks inside small targets and outside every box")
    ap.add_argument("--loo", type=Path, metavar="WORK", help="hard negatives mined on the other clips, per fold")
    ap.add_argument("--clips", help="comma-separated clips (default: every annotated clip)")
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--heat", action="append", metavar="KEY=VALUE", help="the component's heat map (HeatConfig)")
    ap.add_argument("--no-refine", action="store_true", help="the pipelines without the box regressor")
    ap.add_argument("--no-baseline", action="store_true", help="--pipeline: only the run with the component")
    ap.add_argument("--threshold", type=float, help="the component's search threshold (decision value)")
    ap.add_argument("--check", help="the main model's check of its boxes: a decision value, or 'off'")
    ap.add_argument("--json", type=Path, help="write every figure here")
    args = ap.parse_args(argv)
    data = args.data or data_dir()
    clips = annotated_clips(data)
    if args.clips:
        want = args.clips.split(",")
        clips = [c for c in clips if c.name in want]
    config = PipelineConfig()
    if args.heat:
        config = replace(config, small_heat=replace(config.small_heat, **overrides(args.heat, HeatConfig, "--heat")))
    if args.no_refine:
        config = config.without("refine")
    if args.check is not None:
        config = replace(config, small_check=None if args.check == "off" else float(args.check))
    if args.threshold is not None:
        config = replace(config, small_search=replace(config.small_search, threshold=args.threshold))
    report: dict[str, Any] = {"model": args.model, "small_heat": config.small_heat.to_dict(),
                              "small_threshold": config.small_search.threshold, "small_check": config.small_check,
                              "refine": config.refine is not None}
    if args.windows:
        res = windows_study(load_model(args.model), clips, data)
        print_windows(res)
        report["windows"] = res
    if args.pipeline:
        res = pipeline_study(config, args.model, clips, not args.no_baseline)
        if res["without"]:
            print("without the component:\n" + markdown_table(res["without"]))
        print("with the component:\n" + markdown_table(res["with"]))
        report["pipeline"] = res["rows"]
    if args.loo:
        res = loo_study(config, args.model, clips, data, args.loo, not args.no_baseline)
        if res["without"]:
            print("without the component:\n" + markdown_table(res["without"]))
        print("with the component, hard negatives from the other clips (leave one camera out):\n"
              + markdown_table(res["with"]))
        report["loo"] = {"rows": res["rows"], "models": res["models"]}
    if args.peaks:
        peaks = {}
        cfg = replace(config, small=args.model)
        for clip in clips:
            pk = heat_peaks(clip, cfg, data)
            peaks[clip.name] = pk
            sm, fa = np.array(pk["small"]), np.array(pk["false"])
            print(f"{clip.name}: small targets {len(sm)}, peak heat inside (median / 75th pct) "
                  f"{np.median(sm) if len(sm) else float('nan'):.2f} / "
                  f"{np.percentile(sm, 75) if len(sm) else float('nan'):.2f}, above 2/3/4/6/8: "
                  f"{[int((sm > t).sum()) for t in (2, 3, 4, 6, 8)]}; false peak per frame (median / 90th pct) "
                  f"{np.median(fa):.2f} / {np.percentile(fa, 90):.2f}, frames above 2/3/4/6/8: "
                  f"{[int((fa > t).sum()) for t in (2, 3, 4, 6, 8)]} of {len(fa)}", flush=True)
        report["peaks"] = peaks
    if args.cost:
        c = search_cost(config, args.model)
        print("full scan of a 1280x720 frame: " + ", ".join(
            f"{k} {c[f'without_{k}']:.0f} -> {c[f'with_{k}']:.0f} ({c[f'ratio_{k}']:.3f}x)"
            for k in ("hog_cells", "windows", "score_macs")))
        report["cost"] = c
    if args.json:
        args.json.write_text(json.dumps(report, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Search bands from the camera's geometry (tools/studies/perspective.py) on every annotated clip,
beside today's bands (run by hand).

Runs the video pipeline (``iter_video_detections``, the code behind ``fastdet video``) on each
clip with the main model's search replaced by a :class:`~tools.studies.perspective.GeometricSearch`
and, unless ``--fixed-ratio``, the ratio estimated from the tracked boxes as the video goes
(:class:`~tools.studies.perspective.RatioEstimator`, boxes whose score is at least
``--min-score``). Prints the per-clip table of ``fastdet eval --all`` plus the estimated
ratio, the main search's cost (HOG cells of the scaled bands of a full scan, relative to
today's bands at the same horizon) and the windows the pipeline scored per frame (the main
model's and all models'; the guided search scores fewer between full scans).

    python -m tools.studies.geometry_study [--ratio 1.9] [--slack 0.05] [--fixed-ratio]
        [--horizon auto|off|F|+D] [--clips A,B] [--out R.json] [--baseline]
        [--band-slack ABOVE,0] [--slack-threshold D]
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

from fastdet.config import PipelineConfig, SearchBand, SearchConfig
from fastdet.detect.bands import band_geometry
from fastdet.detections import Detections
from fastdet.eval.clips import annotated_clips, markdown_table, report_json, score_clip
from fastdet.io.reader import FrameReader
from fastdet.video import iter_video_detections, make_detector
from fastdet.video.horizon import HORIZON_FRAMES, estimate_horizon
from tools.studies.band_cost import count_scored
from tools.studies.perspective import (
    GeometricSearch,
    GeometryConfig,
    PerspectiveConfig,
    PerspectiveUpdater,
    RatioEstimator,
)
from tools.studies.tolerance import parse_slack


def cells(search: SearchConfig, shape: tuple[int, int], config) -> int:
    """HOG cells of the scaled bands: what the main search costs per frame (roughly)."""
    s = search.for_frame(shape)
    n = 0
    for b in s.bands:
        g = band_geometry(b, shape, config, s.cells_per_step, s.border, s.border_mode)
        n += (g.scaled_w // 8) * (g.scaled_h // 8)
    return n


def first_frames(video, n=HORIZON_FRAMES):
    r = FrameReader(video)
    try:
        for i, (_, f, _) in enumerate(r):
            if i >= n:
                break
            yield f
    finally:
        r.close()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ratio", type=float, default=1.9, help="the prior ratio")
    ap.add_argument("--slack", type=float, default=0.05)
    ap.add_argument("--fixed-ratio", action="store_true")
    ap.add_argument("--joint", action="store_true", help="estimate the horizon and the ratio together")
    ap.add_argument("--min-tracks", type=int, default=2, help="--joint: tracks before there is an estimate")
    ap.add_argument("--prior-frames", type=int, default=None,
                    help="--joint: frames the slack lasts without an estimate")
    ap.add_argument("--settled-slack", type=float, default=0.0, help="--joint: the slack once there is an estimate")
    ap.add_argument("--min-score", type=float, default=10.0)
    ap.add_argument("--horizon", default="auto", help="auto, off, F or +D / -D (the estimate moved by D)")
    ap.add_argument("--baseline", action="store_true", help="today's bands (no geometry)")
    ap.add_argument("--clips", default=None)
    ap.add_argument("--bands", default=None,
                    help="reference bands scale:y0:y1[:x0:x1],... (1280x720 px) instead of today's")
    ap.add_argument("--band-slack", default=None, metavar="ABOVE,0",
                    help="slack (fraction of H) above every main band but the smallest (SearchBand.slack_above) "
                         "instead of the default's (slack below the bands was deleted: BELOW must be 0)")
    ap.add_argument("--slack-threshold", type=float, default=None,
                    help="decision value a window in a band's slack rows must exceed (SearchConfig.slack_threshold; "
                         "'nan': none)")
    ap.add_argument("--residuals", choices=("rows", "log"), default="log",
                    help="--joint: how a box's misfit is measured (PerspectiveConfig.residuals)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    geo = GeometryConfig(ratio=args.ratio, slack=args.slack)
    clips = annotated_clips()
    if args.clips:
        want = args.clips.split(",")
        clips = [c for c in clips if c.name in want]
    scores, extra = [], {}
    for clip in clips:
        horizon: float | str | None = args.horizon
        if args.horizon == "off":
            horizon = None
        elif args.horizon[0] in "+-":
            est = estimate_horizon(first_frames(clip.video))
            base = est if est is not None else SearchConfig().reference_horizon
            horizon = min(max(base + float(args.horizon), 0.0), 1.0)
        elif args.horizon != "auto":
            horizon = float(args.horizon)
        det = make_detector()
        if args.bands:
            bands = []
            for item in args.bands.split(","):
                p = item.split(":")
                bands.append(SearchBand(float(p[0]), int(p[1]), int(p[2]), int(p[3]) if len(p) > 3 else None,
                                        int(p[4]) if len(p) > 4 else None))
            det.scorers[0].search = replace(det.scorers[0].search, bands=tuple(bands))
        if args.band_slack is not None:
            above = parse_slack(args.band_slack)
            main = det.scorers[0].search
            smallest = min(b.scale for b in main.bands)
            det.scorers[0].search = replace(main, bands=tuple(
                b if b.scale == smallest else replace(b, slack_above=above) for b in main.bands))
        if args.slack_threshold is not None:
            gate = None if args.slack_threshold != args.slack_threshold else args.slack_threshold
            det.scorers[0].search = replace(det.scorers[0].search, slack_threshold=gate)
        base_search = det.scorers[0].search
        if not args.baseline:
            det.scorers[0].search = GeometricSearch.from_search(base_search, geo)
        scored = count_scored(det)  # windows scored (main model, all models) over the clip's frames
        est = RatioEstimator()
        updater = None
        frames = []
        shape = None
        cpu0 = None
        config = PipelineConfig(horizon=horizon)
        for fno, dets in iter_video_detections(clip.video, config, detector=det, progress=False):
            if cpu0 is None:  # after the first frame: start-up (kernels, the horizon's flow) left out
                cpu0 = time.process_time()
            frames.append((fno, dets))
            if shape is None:
                r = FrameReader(clip.video)
                shape = r.shape[:2]
                r.close()
            if args.baseline or args.fixed_ratio or dets.ids is None:
                continue
            h = det.horizon if det.horizon is not None else base_search.reference_horizon
            keep = dets.scores >= args.min_score
            if args.joint:
                if updater is None:
                    updater = PerspectiveUpdater(det, PerspectiveConfig(
                        geometry=geo, settled_slack=args.settled_slack, min_tracks=args.min_tracks,
                        min_score=args.min_score, prior_frames=args.prior_frames, residuals=args.residuals))
                updater.update(dets, shape[0])
                continue
            est.update(dets.boxes[keep], dets.ids[keep], h, shape[0])
            r = est.estimate
            if r is not None:
                det.scorers[0].search = replace(det.scorers[0].search, ratio=r)
        cpu_ms = (time.process_time() - cpu0) / max(len(frames) - 1, 1) * 1e3 if cpu0 is not None else float("nan")
        preds = Detections.from_frames(frames, source=str(clip.video))
        s = score_clip(clip.name, clip.gt(), preds, shape[0], clip.keyframes())
        scores.append(s)
        h_used = det.horizon if det.horizon is not None else base_search.reference_horizon
        ref_cells = cells(replace(base_search, horizon=det.horizon), shape, det.config)
        extra[clip.name] = {"horizon": h_used, "ratio": getattr(det.scorers[0].search, "ratio", None),
                            "cells": cells(det.scorers[0].search, shape, det.config), "ref_cells": ref_cells,
                            "cpu_ms_per_frame": cpu_ms, "main_windows_per_frame": scored[0] / max(len(frames), 1),
                            "windows_per_frame": scored[1] / max(len(frames), 1)}
        print(f"{clip.name}: F1 {s.result.f1:.3f} horizon {h_used:.3f} ratio {extra[clip.name]['ratio']} "
              f"cost {extra[clip.name]['cells'] / ref_cells:.2f}x (full scan), windows scored / frame: main "
              f"{scored[0] / max(len(frames), 1):.0f}, all {scored[1] / max(len(frames), 1):.0f}; "
              f"cpu {cpu_ms:.0f} ms/frame", flush=True)
    print(markdown_table(scores))
    if args.out:
        rep = report_json(scores, vars(args))
        for k, v in extra.items():
            rep["clips"][k]["study"] = v
        with open(args.out, "w") as f:
            json.dump(rep, f, indent=1)


if __name__ == "__main__":
    main()

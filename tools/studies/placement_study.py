"""Where the main search's windows are, against the annotated vehicles of every clip (run by hand).

For each keyframe target (``consider`` = 1) of each annotated clip: is there a window of the
main model's search at IoU >= 0.5 with it (**placed**), and does one of those fire (decision
value above the threshold: **fires**)? Beside the search at the horizon the video pipeline
would use (``--horizon auto``: :class:`~fastdet.video.horizon.HorizonEstimator` over the first
frames), the same model searching every row at every scale of the search (``everywhere``:
what placement could give at most). Also the positive windows per keyframe that overlap no
target or ignore box (IoU < 0.3 with all): the raw material of false alarms. Frame by frame,
no heat map and no tracking: it says whether the bands are in the right place, not what the
pipeline scores.

    python -m tools.studies.placement_study [--horizon auto|off|F] [--clips A,B] [--geometric SLACK]
"""
from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from fastdet.boxes import iou
from fastdet.config import SearchBand
from fastdet.detect.bands import window_boxes
from fastdet.eval.clips import annotated_clips
from fastdet.io.reader import read_frames
from fastdet.video import make_detector
from fastdet.video.horizon import HORIZON_FRAMES, HorizonEstimator, search_horizon
from tools.studies.perspective import GeometricSearch, GeometryConfig


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--horizon", default="auto", help="auto (the estimate), off (the reference) or F")
    ap.add_argument("--clips", default=None)
    ap.add_argument("--geometric", type=float, default=None,
                    help="a GeometricSearch with this slack (fraction of H) instead of today's bands")
    ap.add_argument("--ratio", type=float, default=1.9, help="--geometric: the camera's ratio")
    args = ap.parse_args()
    clips = annotated_clips()
    if args.clips:
        clips = [c for c in clips if c.name in args.clips.split(",")]
    print("| clip | horizon | targets | placed | fires | placed everywhere | fires everywhere | "
          "windows / frame | stray positives / keyframe |")
    print("|---|---|---|---|---|---|---|---|---|")
    for clip in clips:
        frames = read_frames(clip.video)
        shape = frames[0].shape[:2]
        if args.horizon == "auto":
            est = HorizonEstimator()
            for f in frames[:HORIZON_FRAMES]:
                if est.done:
                    break
                est.update(f)
            horizon = search_horizon(est.estimate)
        else:
            horizon = None if args.horizon == "off" else float(args.horizon)
        det = make_detector()
        det.set_horizon(horizon)
        if args.geometric is not None:
            s = det.scorers[0].search
            geometry = GeometryConfig(ratio=args.ratio, slack=args.geometric)
            det.scorers[0].search = GeometricSearch.from_search(s, geometry)
        main_search = det.scorers[0].search
        everywhere = replace(main_search.for_frame(shape), bands=tuple(
            SearchBand(b.scale, 0, shape[0]) for b in main_search.for_frame(shape).bands))
        gt = np.loadtxt(clip.gt_path, delimiter=",", ndmin=2)
        kf = clip.keyframes()
        fnos = sorted(set(gt[:, 0].astype(int))) if kf is None else [int(k) for k in kf]
        counts = np.zeros(4, int)
        n_t, stray, n_win = 0, 0, []
        for which, search in (("here", main_search), ("everywhere", everywhere)):
            det.scorers[0].search = search
            for fno in fnos:
                if fno - 1 >= len(frames):
                    continue
                rows = gt[gt[:, 0] == fno]
                t = rows[rows[:, 6] == 1]
                tb = np.c_[t[:, 2], t[:, 3], t[:, 2] + t[:, 4], t[:, 3] + t[:, 5]]
                ab = np.c_[rows[:, 2], rows[:, 3], rows[:, 2] + rows[:, 4], rows[:, 3] + rows[:, 5]]
                geos = det.geometries(shape, 0)
                allw = [window_boxes(g, *np.divmod(np.arange(g.n_windows), g.nx), det.config) for g in geos]
                wins = np.concatenate(allw) if allw else np.zeros((0, 4))
                pos = det.detect(frames[fno - 1])
                pb = pos.boxes[pos.part == 0].astype(float) if pos.part is not None else pos.boxes.astype(float)
                k = 0 if which == "here" else 2
                if which == "here":
                    n_t += len(tb)
                    n_win.append(len(wins))
                    if len(pb):
                        stray += int((iou(pb, ab).max(1) < 0.3).sum() if len(ab) else len(pb))
                if len(tb):
                    counts[k] += int((iou(tb, wins.astype(float)).max(1) >= 0.5).sum())
                    if len(pb):
                        counts[k + 1] += int((iou(tb, pb).max(1) >= 0.5).sum())
        h = horizon if horizon is not None else main_search.reference_horizon
        print(f"| {clip.name} | {h:.3f} | {n_t} | {counts[0]} | {counts[1]} | {counts[2]} | {counts[3]} | "
              f"{np.mean(n_win):.0f} | {stray / max(len(fnos), 1):.1f} |", flush=True)


if __name__ == "__main__":
    main()

"""The horizon of every annotated clip: what its annotated boxes imply, what the optical flow
and the line segments give (run by hand; docs/geometry.md).

Per clip (per shot: ``--cut CLIP:FRAME`` splits a clip at a cut, the first frame of the new
shot):

- **boxes, Theil-Sen**: the line ``w = ratio x (y_bottom - horizon x H)`` through the
  targets' (``consider`` = 1) widths and bottom rows, fitted by Theil-Sen (robust to a few
  vehicles of another width, e.g. seen from the side); ``ratio`` per px of rows.
- **boxes, per track**: the horizon and ratio of
  :class:`tools.studies.perspective.PerspectiveEstimator` over the same boxes grouped by
  vehicle (each vehicle's boxes must agree; no prior), with the default spreads (tight) and
  twice them (loose). Both fits need vehicles at several depths: where all stand at about
  one depth (``y_bottom`` range printed) neither says much.
- **flow**: :class:`fastdet.video.horizon.HorizonEstimator` over the first
  ``HORIZON_FRAMES`` frames with the line segments off: pairs with a FOE, their median row
  and spread (median absolute deviation), and the estimate (``None`` when the spread is over
  ``MAX_SPREAD``); also the median flow per frame (px at 360 rows) and, with
  ``--gaps``, the same at other gaps.
- **segments**: the vanishing point of the line segments (:mod:`fastdet.video.vanishing`) of
  one frame in three of the same frames: frames with one, median row, spread.
- **estimate**: what the default estimator gives and from which cue.

``--cost`` prints instead, per clip, what the default estimator costs as ``fastdet video``
primes it (frames fed until it is done or ``HORIZON_FRAMES`` went by, then the estimate):
frames fed, the line-segment detections it ran (vanishing points) and their CPU (this
thread's), the estimator's CPU in all, and the estimate in full precision.

These are evaluation only: nothing here is a setting.

    python -m tools.studies.horizon_study [--clips A,B] [--cut motorcycle_highway:65] [--gaps 2,4,8] [--cost]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.stats import theilslopes

from fastdet.eval.clips import annotated_clips
from fastdet.io.reader import read_frames
from fastdet.video import horizon
from fastdet.video.horizon import HORIZON_FRAMES, WORK_ROWS, HorizonEstimator, median_flow
from fastdet.video.vanishing import vanishing_point
from tools.studies.perspective import PerspectiveEstimator


def box_fits(t: np.ndarray, rows: int) -> dict:
    """Horizon / ratio fits of the target rows ``t`` of a gt.txt (module docstring)."""
    w, yb = t[:, 4], t[:, 3] + t[:, 5]
    k, c0, _, _ = theilslopes(w, yb)
    out = {"theil": (-c0 / k / rows, k), "bottoms": (yb.min() / rows, yb.max() / rows)}
    boxes = np.c_[t[:, 2], t[:, 3], t[:, 2] + t[:, 4], yb]
    for name, sb, sr in (("track", 0.05, 0.15), ("track_loose", 0.1, 0.3)):
        pe = PerspectiveEstimator(min_boxes=1, min_tracks=1, reach=0.3, grid=0.0025, sigma_h=1e3, sigma_k=1e3,
                                  sigma_r=sr, sigma_box=sb)
        pe.update(boxes, t[:, 1].astype(int), rows)
        est = pe.estimate(0.5, 1.9)
        out[name] = est if est is not None else (float("nan"), float("nan"))
    return out


def med_mad(r: list[float]) -> tuple[float, float]:
    if not r:
        return float("nan"), float("nan")
    a = np.asarray(r)
    m = float(np.median(a))
    return m, float(np.median(np.abs(a - m)))


def fed(est: HorizonEstimator, frames: list[np.ndarray]) -> HorizonEstimator:
    """``est`` after ``frames`` were fed to it in order until it was done."""
    for f in frames:
        if est.done:
            break
        est.update(f)
    return est


def cost(clips: list) -> None:
    """The ``--cost`` table (module docstring)."""
    runs: list[float] = []
    real = horizon.vanishing_point

    def timed(frame: np.ndarray) -> tuple[float, float] | None:
        t0 = time.thread_time()
        try:
            return real(frame)
        finally:
            runs.append(time.thread_time() - t0)

    horizon.vanishing_point = timed  # type: ignore[assignment]
    print("| clip | frames fed | segment detections | their CPU (ms) | estimator CPU (ms) | estimate |")
    print("|---|---|---|---|---|---|")
    try:
        for clip in clips:
            frames = read_frames(clip.video, frames=HORIZON_FRAMES, notify=lambda _n: None)
            runs.clear()
            t0 = time.thread_time()
            est = fed(HorizonEstimator(), frames)
            e = est.estimate
            total = time.thread_time() - t0
            print(f"| {clip.name} | {est.frames} | {len(runs)} | {1000 * sum(runs):.0f} | {1000 * total:.0f} | "
                  f"{e!r} ({est.source}) |", flush=True)
    finally:
        horizon.vanishing_point = real


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--clips", default=None)
    ap.add_argument("--cut", action="append", default=["motorcycle_highway:65"],
                    help="CLIP:FRAME, the 1-based first frame after a cut (repeatable)")
    ap.add_argument("--gaps", default="", help="also the flow estimate at these gaps (comma-separated)")
    ap.add_argument("--cost", action="store_true", help="the default estimator's cost instead (module docstring)")
    args = ap.parse_args()
    cuts = {c.split(":")[0]: int(c.split(":")[1]) for c in args.cut}
    clips = annotated_clips()
    if args.clips:
        clips = [c for c in clips if c.name in args.clips.split(",")]
    if args.cost:
        cost(clips)
        return
    print("| clip | shot | boxes (targets, tracks) | bottoms (of H) | Theil-Sen horizon / ratio | per track "
          "horizon / ratio (tight; loose) | flow: pairs, median, spread | flow / frame (px at 360) | "
          "segments: frames, median, spread | estimate |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for clip in clips:
        frames = read_frames(clip.video)
        rows = frames[0].shape[0]
        gt = np.loadtxt(clip.gt_path, delimiter=",", ndmin=2)
        t_all = gt[gt[:, 6] == 1]
        cut = cuts.get(clip.name)
        shots = [(1, len(frames))] if cut is None else [(1, cut - 1), (cut, len(frames))]
        for a, b in shots:
            t = t_all[(t_all[:, 0] >= a) & (t_all[:, 0] <= b)]
            fits = box_fits(t, rows) if len(t) >= 2 else None
            fr = frames[a - 1:b][:HORIZON_FRAMES]
            flow = fed(HorizonEstimator(segments=False), fr)
            per_frame = []
            for j in range(0, len(fr) - 1, 6):
                per_frame.append(median_flow(fr[j], fr[j + 1]) * 360 / min(WORK_ROWS, rows))
            seg = [p[1] / rows for p in (vanishing_point(f) for f in fr[::3]) if p is not None]
            est = fed(HorizonEstimator(), fr)
            fm, fs = med_mad(flow.rows)
            sm, ss = med_mad(seg)
            if fits is None:
                box = "-", "-", "-", "-"
            else:
                box = (f"{fits['bottoms'][0]:.3f}-{fits['bottoms'][1]:.3f}",
                       f"{fits['theil'][0]:.3f} / {fits['theil'][1]:.2f}",
                       f"{fits['track'][0]:.3f} / {fits['track'][1]:.2f}; "
                       f"{fits['track_loose'][0]:.3f} / {fits['track_loose'][1]:.2f}", "")
            e = "none" if est.estimate is None else f"{est.estimate:.3f} ({est.source})"
            extra = ""
            for gap in [int(g) for g in args.gaps.split(",") if g]:
                h = fed(HorizonEstimator(gap=gap, segments=False), fr)
                gm, gs = med_mad(h.rows)
                extra += f"; gap {gap}: {gm:.3f} / {gs:.3f}"
            print(f"| {clip.name} | {a}-{b} | {len(t)}, {len(set(t[:, 1].astype(int)))} | {box[0]} | {box[1]} | "
                  f"{box[2]} | {len(flow.rows)}, {fm:.3f}, {fs:.3f}{extra} | {np.median(per_frame):.2f} | "
                  f"{len(seg)}, {sm:.3f}, {ss:.3f} | {e} |", flush=True)


if __name__ == "__main__":
    main()

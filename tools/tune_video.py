"""Sweep detector threshold and heat-map settings on the annotated clips (run by hand).

Runs the Detector once per frame of every clip in ``$FASTDET_DATA/annotations`` with a low
window threshold, caches the windows, then replays the heat map for each setting and
evaluates like ``python -m fastdet eval`` (IoU 0.5). Prints one markdown row per setting.
With ``--wide`` it replays a wide-window model's heat map too, but without the motion gate
of ``VideoDetector`` (tools/accuracy_report.py runs that through the real pipeline).

    python tools/tune_video.py [--model M.npz] [--grid small|wide] [--frames-from K]
"""
from __future__ import annotations

import argparse
import itertools
from dataclasses import replace

import cv2
import numpy as np

from fastdet.config import HeatConfig, SearchConfig
from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.detector import Detector
from fastdet.eval import evaluate
from fastdet.heatmap import HeatMap
from fastdet.motio import GroundTruth, Predictions, read_gt


def cache_windows(det: Detector, video, low: float):
    cap = cv2.VideoCapture(str(video))
    out = []
    shape = (720, 1280)
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        det.detect(frame)
        shape = frame.shape[:2]
        boxes, decs, parts = [], [], []
        from fastdet.search import window_boxes

        for (geo, dec), part in zip(det.last_band_scores, det.last_band_parts):
            r, c = np.nonzero(dec > low)
            boxes.append(window_boxes(geo, r, c, det.scorers[part].config))
            decs.append(dec[r, c])
            parts.append(np.full(len(r), part))
        out.append((np.concatenate(boxes), np.concatenate(decs), np.concatenate(parts)))
    return out, shape


def replay(cache, shape, thr: float, heat: HeatConfig, kind: str, first: int = 1, thr_wide: float | None = None,
           wide_heat: HeatConfig | None = None):
    from fastdet.fusion import merge_wide

    hm = HeatMap(shape, heat, score_kind=kind)
    hw = HeatMap(shape, wide_heat, score_kind=kind) if wide_heat is not None else None
    frames = []
    thr_wide = thr if thr_wide is None else thr_wide
    sig = (lambda v: 1 / (1 + np.exp(-v))) if kind == "probability" else (lambda v: v)
    for i, (boxes, dec, parts) in enumerate(cache, start=1):
        if hw is None:
            keep = np.where(parts == 0, dec > thr, dec > thr_wide)
            d = hm.update(Detections(boxes[keep], sig(dec[keep]).astype(np.float32)))
        else:
            km = (parts == 0) & (dec > thr)
            kw = (parts == 1) & (dec > thr_wide)
            d = merge_wide(hm.update(Detections(boxes[km], sig(dec[km]).astype(np.float32))),
                           hw.update(Detections(boxes[kw], sig(dec[kw]).astype(np.float32))))
        if i >= first:
            frames.append((i, d))
    return Predictions.from_frames(frames)


def evaluate_from(gt: GroundTruth, preds: Predictions, first: int, n_frames: int):
    """Evaluate frames ``first .. n_frames`` only (IoU 0.5), as if the clip began at ``first``."""
    sel, psel = gt.frames >= first, preds.frames >= first
    sub = GroundTruth(gt.frames[sel] - first + 1, gt.ids[sel], gt.boxes[sel], gt.consider[sel])
    p = Predictions(preds.frames[psel] - first + 1, preds.ids[psel], preds.boxes[psel], preds.scores[psel])
    return evaluate(sub, p, iou=0.5, num_frames=n_frames - first + 1)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", default=None)
    ap.add_argument("--low", type=float, default=-1.0)
    ap.add_argument("--thr", default="0,0.5,1")
    ap.add_argument("--thr-wide", default="0")
    ap.add_argument("--no-wide", action="store_true")
    ap.add_argument("--wide", default=None, help="wide model file")
    ap.add_argument("--heat-thr", default="1,2,3,4,6")
    ap.add_argument("--n-frames", default="8")
    ap.add_argument("--decay", default="0.8")
    ap.add_argument("--extent", default="0.4")
    ap.add_argument("--w-max", default="4")
    ap.add_argument("--step", type=int, default=None)
    ap.add_argument("--bands", default=None, help="scale:y0:y1,... instead of the default bands")
    ap.add_argument("--separate", action="store_true", help="wide windows in their own heat map")
    ap.add_argument("--wide-heat-thr", default="4")
    ap.add_argument("--wide-n", default="4")
    ap.add_argument("--wide-extent", default="0.4")
    ap.add_argument("--wide-max-aspect", default="0.8")
    ap.add_argument("--wide-box", default="extent")
    ap.add_argument("--box", default="extent")
    ap.add_argument("--first-per-clip", default="", help="e.g. test_small1=67,test_video=20")
    ap.add_argument("--first", type=int, default=1, help="evaluate frames >= this only (0: the second half)")
    args = ap.parse_args()
    fl = lambda s: [float(v) for v in s.split(",")]
    search = SearchConfig() if args.step is None else replace(SearchConfig(), cells_per_step=args.step)
    if args.bands:
        from fastdet.config import SearchBand

        bands = [b.split(":") for b in args.bands.split(",")]
        search = replace(search, bands=tuple(SearchBand(float(a), int(b), int(c)) for a, b, c in bands))
    det = Detector(args.model, search, wide=None if args.no_wide else args.wide)
    kind = det.score_kind
    clips = sorted((data_dir() / "annotations").glob("*.gt.txt"))
    caches = {}
    for gt_path in clips:
        name = gt_path.name[: -len(".gt.txt")]
        caches[name] = (read_gt(gt_path), *cache_windows(det, data_dir() / "videos" / f"{name}.mp4", args.low))
    print("| thr | wide thr | heat thr | n | decay | extent | w_max | " + " | ".join(f"{n} P R F1 AP FP/f" for n in caches) + " | min F1 |")
    rows = []
    grid = itertools.product(fl(args.thr), fl(args.thr_wide), fl(args.heat_thr), fl(args.n_frames), fl(args.decay),
                             fl(args.extent), fl(args.w_max), fl(args.wide_heat_thr), fl(args.wide_n),
                             fl(args.wide_extent), fl(args.wide_max_aspect))
    for thr, tw, ht, n, dc, ex, wm, wht, wn, wex, wma in grid:
        heat = replace(HeatConfig(), threshold=ht, n_frames=int(n), decay=dc, extent=ex, w_max=wm, box_mode=args.box)
        wheat = (replace(heat, threshold=wht, n_frames=int(wn), extent=wex, max_aspect=wma, min_height=10,
                         box_mode=args.wide_box)
                 if args.separate else None)
        cells, f1s = [], []
        for name, (gt, cache, shape) in caches.items():
            per_clip = dict(kv.split("=") for kv in args.first_per_clip.split(",")) if args.first_per_clip else {}
            first = int(per_clip.get(name, args.first)) or len(cache) // 2 + 1
            r = evaluate_from(gt, replay(cache, shape, thr, heat, kind, first, tw, wheat), first, len(cache))
            cells.append(f"{r.precision:.2f} {r.recall:.2f} **{r.f1:.2f}** {r.ap:.2f} {r.fp_per_frame:.2f}")
            f1s.append(r.f1)
        if args.separate:
            tw = f"{tw:g} w{wht:g}/{int(wn)}/{wex:g}/{wma:g}"
        line = f"| {thr:g} | {tw} | {ht:g} | {int(n)} | {dc:g} | {ex:g} | {wm:g} | " + " | ".join(cells) + f" | {min(f1s):.3f} |"
        rows.append((min(f1s), line))
        print(line, flush=True)
    print("\nbest:")
    for _, line in sorted(rows, reverse=True)[:5]:
        print(line)


if __name__ == "__main__":
    main()

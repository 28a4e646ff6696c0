"""The README accuracy table: the classic pipeline, fastdet's defaults, and the ablations.

Every row runs a detector over every frame of every annotated clip in
``$FASTDET_DATA/annotations``, replays a heat map and evaluates at IoU 0.5 exactly as
``python -m fastdet eval`` does. The "fastdet defaults" row is also recomputed through
``fastdet.video.iter_video_detections`` (the code behind ``python -m fastdet video``) and
must agree. Usage::

    python tools/accuracy_report.py --classic-model classic.npz [--wide-model wide.npz]

``classic.npz``: ``python -m fastdet train --classifier linearsvc --C 1 --orientations 9
--no-flip --out classic.npz`` (the classic recipe). Scores of the classic per-window
pipeline equal fastdet's dense scores to 1e-6 (tests/test_detector.py), so its rows use
the fast scorer on the same bands.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from tune_video import cache_windows, evaluate_from, replay  # noqa: E402

from fastdet.config import WIDE_HEAT, HeatConfig, SearchConfig  # noqa: E402
from fastdet.data import data_dir  # noqa: E402
from fastdet.detector import Detector  # noqa: E402
from fastdet.eval import evaluate  # noqa: E402
from fastdet.motio import Predictions, read_gt  # noqa: E402

#: the classic write-ups' heat map: +1 per positive window, summed over 8 frames, threshold
#: 6, the whole blob, boxes < 40 px wide or taller than 1.5 x width dropped. HeatMap keeps
#: a mean over the frames seen, so "sum > 6 over 8 frames" is "mean > 0.75".
CLASSIC_HEAT = HeatConfig(n_frames=8, decay=1.0, threshold=0.75, w_max=1.0, extent=0.0, min_width=40,
                          min_height=1, max_aspect=1.5)



def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--classic-model", required=True)
    ap.add_argument("--wide-model", default=None)
    ap.add_argument("--held-out", default="test_small1=67,test_video=20",
                    help="first frame never used for mining/training, per clip")
    args = ap.parse_args()
    held = {k: int(v) for k, v in (kv.split("=") for kv in args.held_out.split(","))}
    clips = sorted((data_dir() / "annotations").glob("*.gt.txt"))
    names = [p.name[: -len(".gt.txt")] for p in clips]
    gts = {n: read_gt(p) for n, p in zip(names, clips)}
    videos = {n: data_dir() / "videos" / f"{n}.mp4" for n in names}

    def caches(det):
        return {n: cache_windows(det, videos[n], -1.0) for n in names}

    rows = []
    classic = Detector(args.classic_model)
    fast = Detector()
    one_cell = Detector(search=replace(SearchConfig(), cells_per_step=1))
    c_classic, c_fast, c_one = caches(classic), caches(fast), caches(one_cell)
    d = HeatConfig()
    thr = SearchConfig().threshold
    rows.append(("classic pipeline (YCrCb 9/8/2 + 32x32 + 32 bins, LinearSVC C=1; +1 per window over 8 frames > 6)",
                 c_classic, classic.score_kind, CLASSIC_HEAT, None))
    rows.append(("fastdet model (16 orientations, flips, logistic regression C=0.03), classic heat map",
                 c_fast, fast.score_kind, CLASSIC_HEAT, None))
    rows.append((f"+ confidence-weighted heat (1..4 per window), decay {d.decay:g}, threshold {d.threshold:g}, whole blob",
                 c_fast, fast.score_kind, replace(d, extent=0.0), None))
    rows.append(("**fastdet defaults** (+ box = blob cells >= 0.4 x peak)", c_fast, fast.score_kind, d, None))
    rows.append(("defaults, but windows at a 1-cell step", c_one, one_cell.score_kind, d, None))
    rows.append(("defaults, box = heat-weighted mean of the blob's windows", c_fast, fast.score_kind,
                 replace(d, box_mode="mean"), None))
    if args.wide_model:
        wide = Detector(wide=args.wide_model)
        rows.append(("defaults + wide-window model (own heat map), see below", caches(wide), wide.score_kind, d,
                     WIDE_HEAT))
    from fastdet.config import WIDE_SEARCH

    wide_thr = WIDE_SEARCH.threshold
    head = " | ".join(f"{n} P / R / F1 / AP / FP per frame" for n in names)
    print(f"| setting | {head} | held-out frames ({', '.join(f'{n} >= {held[n]}' for n in names)}) F1 |")
    print("|---|" + "---|" * len(names) + "---|")
    for label, cache, kind, heat, wheat in rows:
        cells, held_f1 = [], []
        for n in names:
            cch, shape = cache[n]
            preds = replay(cch, shape, thr, heat, kind, 1, wide_thr, wheat)
            r = evaluate(gts[n], preds, iou=0.5, num_frames=len(cch))
            cells.append(f"{r.precision:.2f} / {r.recall:.2f} / **{r.f1:.2f}** / {r.ap:.2f} / {r.fp_per_frame:.2f}")
            held_f1.append(f"{evaluate_from(gts[n], preds, held[n], len(cch)).f1:.2f}")
        print(f"| {label} | " + " | ".join(cells) + f" | {' / '.join(held_f1)} |", flush=True)
    # cross-check the defaults row against the code path of `python -m fastdet video`
    from fastdet.video import iter_video_detections

    for n in names:
        preds = Predictions.from_frames(iter_video_detections(videos[n], progress=False))
        r = evaluate(gts[n], preds, iou=0.5)
        print(f"\ncheck, `python -m fastdet eval --video {n}.mp4`: F1 {r.f1:.3f}, AP {r.ap:.3f}", end="")
    print()


if __name__ == "__main__":
    main()

"""The accuracy table of docs/accuracy.md (*The Udacity clips, step by step*): the classic
pipeline, fastdet's defaults, and the ablations.

Every row runs a detector over every frame of every annotated clip in
``$FASTDET_DATA/annotations`` and evaluates at IoU 0.5 exactly as ``python -m fastdet
eval`` does. Each detector's windows are cached once per clip, then every row runs the real
``fastdet.VideoDetector`` over the clip with the row's settings on those windows
(``tools/studies/tune_video.py``: ``cache_windows``, ``replay``); the defaults row runs
``iter_video_detections``, the code behind ``python -m fastdet video``. Usage (from the
project root)::

    python -m tools.studies.accuracy_report --classic-model classic.npz

``classic.npz``: ``python -m fastdet train --classifier linearsvc --C 1 --orientations 9
--no-flip --out classic.npz`` (the classic recipe). Scores of the classic per-window
pipeline equal fastdet's dense scores to 1e-6 (tests/detect/test_detector.py), so its rows use
the fast scorer on the same bands.
"""
from __future__ import annotations

import argparse
from dataclasses import replace

from fastdet import Detector, HeatConfig, MotionGate, SearchConfig
from fastdet.config import ONCOMING_HEAT
from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval import evaluate
from fastdet.io.motfiles import read_gt
from fastdet.video import iter_video_detections, make_detector
from tools.studies.tune_video import cache_windows, replay

#: the classic write-ups' heat map: +1 per positive window, summed over 8 frames, threshold
#: 6, the whole blob, boxes < 40 px wide or taller than 1.5 x width dropped. HeatMap keeps
#: a mean over the frames seen, so "sum > 6 over 8 frames" is "mean > 0.75".
CLASSIC_HEAT = HeatConfig(n_frames=8, decay=1.0, threshold=0.75, w_max=1.0, extent=0.0, min_width=40,
                          min_height=1, max_aspect=1.5)


def _cell(r) -> str:
    """One table cell: P / R / **F1** / AP / FP per frame."""
    return f"{r.precision:.2f} / {r.recall:.2f} / **{r.f1:.2f}** / {r.ap:.2f} / {r.fp_per_frame:.2f}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--classic-model", required=True)
    args = ap.parse_args()
    clips = sorted((data_dir() / "annotations").glob("*.gt.txt"))
    names = [p.name[: -len(".gt.txt")] for p in clips]
    gts = {n: read_gt(p) for n, p in zip(names, clips)}
    videos = {n: data_dir() / "videos" / f"{n}.mp4" for n in names}

    def caches(det):
        return {n: cache_windows(det, videos[n], -1.0) for n in names}

    classic = Detector(args.classic_model)
    fast = Detector()
    one_cell = Detector(search=replace(SearchConfig(), cells_per_step=1))
    c_classic, c_fast, c_one, c_wide = caches(classic), caches(fast), caches(one_cell), caches(make_detector())
    d = HeatConfig()
    thr = SearchConfig().threshold
    # (label, cached windows, heat, motion gate): VideoDetector replayed over the cached windows,
    # without the tracker
    rows = [
        ("classic pipeline (YCrCb 9/8/2 + 32x32 + 32 bins, LinearSVC C=1; +1 per window over 8 frames > 6)",
         c_classic, CLASSIC_HEAT, None),
        ("fastdet model (16 orientations, flips, logistic regression C=0.03), classic heat map",
         c_fast, CLASSIC_HEAT, None),
        (f"+ confidence-weighted heat (1..4 per window), decay {d.decay:g}, threshold {d.threshold:g}, whole blob",
         c_fast, replace(d, extent=0.0), None),
        ("+ box = blob cells >= 0.4 x peak: the main model alone (`--no-oncoming`)", c_fast, d, None),
        ("main model alone, but windows at a 1-cell step", c_one, d, None),
        ("main model alone, box = heat-weighted mean of the blob's windows", c_fast, replace(d, box_mode="mean"), None),
        ("+ oncoming-traffic model, full wide search, no motion gate", c_wide, d, MotionGate(0)),
        ("+ motion gate (search and keep only wide windows that moved): the defaults without the tracker "
         "(`--no-track`)", c_wide, d, MotionGate()),
    ]
    head = " | ".join(f"{n} P / R / F1 / AP / FP per frame" for n in names)
    print(f"| setting | {head} |")
    print("|---|" + "---|" * len(names))
    for label, cache, heat, motion in rows:
        cells = []
        for n in names:
            clip = cache[n]
            preds = replay(clip, thr, heat, ONCOMING_HEAT, motion, tracker=False)
            r = evaluate(gts[n], preds, iou=0.5, num_frames=len(clip))
            cells.append(_cell(r))
        print(f"| {label} | " + " | ".join(cells) + " |", flush=True)
    # the defaults, through the code path of `python -m fastdet video` / `eval`
    cells = []
    for n in names:
        preds = Detections.from_frames(iter_video_detections(videos[n], progress=False))
        cells.append(_cell(evaluate(gts[n], preds, iou=0.5)))
    print("| **fastdet defaults**: + tracker (ids; weak blobs keep a vehicle's track alive) | "
          + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()

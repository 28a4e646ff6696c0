"""The README accuracy table: the classic pipeline, fastdet's defaults, and the ablations.

Every row runs a detector over every frame of every annotated clip in
``$FASTDET_DATA/annotations`` and evaluates at IoU 0.5 exactly as ``python -m fastdet
eval`` does. Rows of the main model alone replay a heat map over cached windows; rows
with the oncoming-traffic model run ``fastdet.video.VideoDetector`` itself (its motion
gate needs the frames), the defaults row through ``iter_video_detections``, the code
behind ``python -m fastdet video``. Usage::

    python tools/accuracy_report.py --classic-model classic.npz

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

from tune_video import cache_windows, replay  # noqa: E402

from fastdet.config import HeatConfig, MotionGate, SearchConfig  # noqa: E402
from fastdet.data import data_dir  # noqa: E402
from fastdet.detector import Detector  # noqa: E402
from fastdet.eval import evaluate  # noqa: E402
from fastdet.motio import Predictions, read_gt  # noqa: E402

#: the classic write-ups' heat map: +1 per positive window, summed over 8 frames, threshold
#: 6, the whole blob, boxes < 40 px wide or taller than 1.5 x width dropped. HeatMap keeps
#: a mean over the frames seen, so "sum > 6 over 8 frames" is "mean > 0.75".
CLASSIC_HEAT = HeatConfig(n_frames=8, decay=1.0, threshold=0.75, w_max=1.0, extent=0.0, min_width=40,
                          min_height=1, max_aspect=1.5)



def _cell(r) -> str:
    """One table cell: P / R / **F1** / AP / FP per frame."""
    return f"{r.precision:.2f} / {r.recall:.2f} / **{r.f1:.2f}** / {r.ap:.2f} / {r.fp_per_frame:.2f}"


def _pipeline_row(label: str, names, videos, gts, **kw) -> str:
    """One row from the real video pipeline: ``kw`` go to VideoDetector (or ``oncoming`` to
    make_detector)."""
    import cv2

    from fastdet.video import VideoDetector, make_detector

    cells = []
    det = make_detector(oncoming=kw.pop("oncoming", True))
    for n in names:
        vd = VideoDetector(det, **kw)
        cap = cv2.VideoCapture(str(videos[n]))
        frames = []
        while (item := cap.read())[0]:
            frames.append((len(frames) + 1, vd.update(item[1])))
        r = evaluate(gts[n], Predictions.from_frames(frames), iou=0.5, num_frames=len(frames))
        cells.append(_cell(r))
    return f"| {label} | " + " | ".join(cells) + " |"


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

    rows = []
    classic = Detector(args.classic_model)
    fast = Detector()
    one_cell = Detector(search=replace(SearchConfig(), cells_per_step=1))
    c_classic, c_fast, c_one = caches(classic), caches(fast), caches(one_cell)
    d = HeatConfig()
    thr = SearchConfig().threshold
    rows.append(("classic pipeline (YCrCb 9/8/2 + 32x32 + 32 bins, LinearSVC C=1; +1 per window over 8 frames > 6)",
                 c_classic, classic.score_kind, CLASSIC_HEAT))
    rows.append(("fastdet model (16 orientations, flips, logistic regression C=0.03), classic heat map",
                 c_fast, fast.score_kind, CLASSIC_HEAT))
    rows.append((f"+ confidence-weighted heat (1..4 per window), decay {d.decay:g}, threshold {d.threshold:g}, whole blob",
                 c_fast, fast.score_kind, replace(d, extent=0.0)))
    rows.append(("+ box = blob cells >= 0.4 x peak: the main model alone (`--no-oncoming`)", c_fast, fast.score_kind, d))
    rows.append(("main model alone, but windows at a 1-cell step", c_one, one_cell.score_kind, d))
    rows.append(("main model alone, box = heat-weighted mean of the blob's windows", c_fast, fast.score_kind,
                 replace(d, box_mode="mean")))
    head = " | ".join(f"{n} P / R / F1 / AP / FP per frame" for n in names)
    print(f"| setting | {head} |")
    print("|---|" + "---|" * len(names))
    for label, cache, kind, heat in rows:
        cells = []
        for n in names:
            cch, shape = cache[n]
            r = evaluate(gts[n], replay(cch, shape, thr, heat, kind), iou=0.5, num_frames=len(cch))
            cells.append(_cell(r))
        print(f"| {label} | " + " | ".join(cells) + " |", flush=True)
    print(_pipeline_row("+ oncoming-traffic model, full wide search, no motion gate", names, videos, gts,
                        motion=MotionGate(0)), flush=True)
    # the defaults, through the code path of `python -m fastdet video` / `eval`
    from fastdet.video import iter_video_detections

    cells = []
    for n in names:
        preds = Predictions.from_frames(iter_video_detections(videos[n], progress=False))
        r = evaluate(gts[n], preds, iou=0.5)
        cells.append(_cell(r))
    print("| **fastdet defaults**: + motion gate (search and keep only wide windows that moved) | "
          + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()

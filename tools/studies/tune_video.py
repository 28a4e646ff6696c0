"""Sweep window thresholds, heat-map settings and the motion gate on the annotated clips
(run by hand).

Detection is the expensive part and does not depend on what comes after it, so each clip's
windows are detected once (:func:`cache_windows`: every window with a decision value above
``--low``). Then, for every setting, the real :class:`fastdet.VideoDetector` runs over the
clip's frames with a :class:`tests.fakes.ReplayDetector` in place of the Detector (:func:`replay`): it
returns the cached windows above the setting's window thresholds, scored as
:meth:`fastdet.Detector.detect` scores them. Everything after detection -- the main and the
oncoming heat map, the oncoming model's motion gate, the fusion of the two -- is VideoDetector's own
code. The boxes are evaluated like ``python -m fastdet eval`` (IoU 0.5). Prints one
markdown row per setting.

The replay returns the oncoming model's windows of its whole search when VideoDetector asks for
some ``oncoming_bands`` (the parts of the search where the picture moved) and none when it asks
for none; VideoDetector then keeps the oncoming windows that moved enough, which are exactly the
windows of the narrowed search, with the same scores to 1e-6 (``tests/video/test_motion.py``
checks both).

    python -m tools.studies.tune_video [--model M.npz] [--oncoming W.npz | --oncoming bundled] [--thr 0,0.5,1] ...
"""
from __future__ import annotations

import argparse
import itertools
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from fastdet import Detections, Detector, HeatConfig, MotionGate, SearchConfig, VideoDetector
from fastdet.config import ONCOMING_HEAT, ONCOMING_SEARCH, PipelineConfig, TrackerConfig
from fastdet.data import data_dir
from fastdet.detect import DetectStats, window_boxes
from fastdet.detect.geometry import row_thresholds
from fastdet.eval import evaluate
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import FrameReader
from fastdet.model import ONCOMING_MODEL_PATH
from tests.fakes import ReplayDetector
from tools.studies.band_cost import parse_bands


@dataclass
class CachedClip:
    """One clip's windows, detected once: per frame, every window whose decision value is
    above the cache's low threshold (``windows[i]`` with ``scale`` and ``part``,
    ``decisions[i]`` their decision values, float64, ``gates[i]`` the decision value the
    detector's own search asks of each where it is stricter than the threshold swept, NaN
    elsewhere: the main bands' slack rows, :func:`fastdet.detect.geometry.row_thresholds`)."""

    video: Path
    detector: Detector
    windows: list[Detections]
    decisions: list[np.ndarray]
    gates: list[np.ndarray]

    def __len__(self) -> int:
        return len(self.windows)


def frames_of(video: str | os.PathLike):
    """The decodable frames of ``video`` (BGR), as the video pipeline reads them."""
    reader = FrameReader(video)
    try:
        for _, frame, _ in reader:
            yield frame
    finally:
        reader.close()


def cache_windows(det: Detector, video: str | os.PathLike, low: float) -> CachedClip:
    """Run ``det`` over every frame of ``video`` once and keep every window (of both models)
    with a decision value above ``low`` (at most the lowest threshold to sweep)."""
    windows, decisions, gates = [], [], []
    for frame in frames_of(video):
        stats = DetectStats()
        det.detect(frame, stats=stats)
        found, decs, gate = [], [], []
        for part, geo, dec in stats.bands:
            scorer = det.scorers[det.parts.index(part)]
            config = scorer.config
            r, c = np.nonzero(dec > low)
            found.append(Detections(window_boxes(geo, r, c, config), dec[r, c].astype(np.float32),
                                    scale=np.full(len(r), geo.band.scale), part=np.full(len(r), part)))
            decs.append(dec[r, c])
            row_thr = np.broadcast_to(row_thresholds(geo, scorer.search, config), (geo.ny,))[r]
            gate.append(np.where(row_thr > scorer.search.threshold, row_thr, np.nan))
        windows.append(Detections.concat(found))
        decisions.append(np.concatenate(decs) if decs else np.zeros(0))
        gates.append(np.concatenate(gate) if gate else np.zeros(0))
    return CachedClip(Path(video), det, windows, decisions, gates)


def replayed_windows(clip: CachedClip, thr: float, thr_oncoming: float) -> list[Detections]:
    """Per frame, the clip's cached windows above ``thr`` (main model) or ``thr_oncoming`` (oncoming
    model), with the scores :meth:`fastdet.Detector.detect` gives them (the probability for
    logistic-regression models, the decision value for LinearSVC)."""
    out = []
    for windows, dec, gate in zip(clip.windows, clip.decisions, clip.gates):
        keep = np.where(windows.is_oncoming, dec > thr_oncoming, dec > thr)
        keep &= ~(dec <= gate)  # a slack row's own, stricter threshold (NaN: none)
        score = dec[keep]
        if clip.detector.score_kind == "probability":
            score = 1.0 / (1.0 + np.exp(-score))
        out.append(replace(windows[keep], scores=score.astype(np.float32)))
    return out


def replay(clip: CachedClip, thr: float, heat: HeatConfig, oncoming_heat: HeatConfig | None = None,
           motion: MotionGate | None = None, thr_oncoming: float = ONCOMING_SEARCH.threshold,
           first: int = 1, tracker: TrackerConfig | bool | None = None) -> Detections:
    """The boxes :class:`fastdet.VideoDetector` (``heat``, ``oncoming_heat``, ``motion``,
    ``tracker``: its arguments) gives on the clip's frames from its cached windows, for frames
    ``first`` (1-based) on."""
    track = TrackerConfig() if tracker is None or tracker is True else (tracker or None)
    config = PipelineConfig(heat=heat, oncoming_heat=oncoming_heat if oncoming_heat is not None else ONCOMING_HEAT,
                            motion=motion if motion is not None else MotionGate(), tracker=track)
    vd = VideoDetector(ReplayDetector(replayed_windows(clip, thr, thr_oncoming), like=clip.detector), config)
    frames = [(i, d) for i, d in enumerate(map(vd.update, frames_of(clip.video)), start=1) if i >= first]
    if vd.detector.frame != len(clip):
        raise RuntimeError(f"{clip.video}: {vd.detector.frame} frames decoded, {len(clip)} cached")
    return Detections.from_frames(frames)


def evaluate_from(gt: Detections, preds: Detections, first: int, n_frames: int):
    """Evaluate frames ``first .. n_frames`` only (IoU 0.5), as if the clip began at ``first``."""
    sel, psel = gt.frames >= first, preds.frames >= first
    sub = gt[sel].with_frames(gt.frames[sel] - first + 1)
    p = preds[psel].with_frames(preds.frames[psel] - first + 1)
    return evaluate(sub, p, iou=0.5, num_frames=n_frames - first + 1)


def main() -> None:
    h, w = HeatConfig(), ONCOMING_HEAT
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--model", default=None, help="main model file (default: the bundled one)")
    ap.add_argument("--oncoming", default=None, help="oncoming-traffic model file, or 'bundled' (default: none)")
    ap.add_argument("--low", type=float, default=-1.0, help="decision value above which windows are cached")
    ap.add_argument("--thr", default="0,0.5,1", help="main model's window thresholds (decision values)")
    ap.add_argument("--thr-oncoming", default=f"{ONCOMING_SEARCH.threshold:g}",
                    help="oncoming model's window thresholds")
    ap.add_argument("--heat-thr", default="1,2,3,4,6")
    ap.add_argument("--n-frames", default="8")
    ap.add_argument("--decay", default="0.8")
    ap.add_argument("--extent", default="0.4")
    ap.add_argument("--w-max", default="4")
    ap.add_argument("--box", default=h.box_mode)
    ap.add_argument("--step", type=int, default=None, help="main search's cells per step")
    ap.add_argument("--bands", default=None, help="scale:y0:y1[:x0:x1],... instead of the default bands")
    ap.add_argument("--oncoming-heat-thr", default=f"{w.threshold:g}")
    ap.add_argument("--oncoming-n", default=f"{w.n_frames}")
    ap.add_argument("--oncoming-extent", default=f"{w.extent:g}")
    ap.add_argument("--oncoming-max-aspect", default=f"{w.max_aspect:g}")
    ap.add_argument("--oncoming-box", default=w.box_mode)
    ap.add_argument("--motion", default=f"{MotionGate().min_motion:g}", help="motion gate thresholds (0: none)")
    ap.add_argument("--first-per-clip", default="", help="e.g. test_small1=67,test_video=20")
    ap.add_argument("--first", type=int, default=1, help="evaluate frames >= this only (0: the second half)")
    ap.add_argument("--no-track", action="store_true", help="the heat maps' boxes, without the tracker")
    args = ap.parse_args()

    def fl(s: str) -> list[float]:
        return [float(v) for v in s.split(",")]

    search = SearchConfig() if args.step is None else replace(SearchConfig(), cells_per_step=args.step)
    if args.bands:
        search = replace(search, bands=parse_bands(args.bands))
    oncoming = ONCOMING_MODEL_PATH if args.oncoming == "bundled" else args.oncoming
    det = Detector(args.model, search, oncoming=oncoming)
    clips = sorted((data_dir() / "annotations").glob("*.gt.txt"))
    caches = {}
    for gt_path in clips:
        name = gt_path.name[: -len(".gt.txt")]
        caches[name] = (read_gt(gt_path), cache_windows(det, data_dir() / "videos" / f"{name}.mp4", args.low))
    per_clip = dict(kv.split("=") for kv in args.first_per_clip.split(",")) if args.first_per_clip else {}
    print("| thr | oncoming thr | heat thr | n | decay | extent | w_max | oncoming heat thr/n/extent/aspect | motion | "
          + " | ".join(f"{n} P R F1 AP FP/f" for n in caches) + " | min F1 |")
    rows = []
    grid = itertools.product(fl(args.thr), fl(args.thr_oncoming), fl(args.heat_thr), fl(args.n_frames), fl(args.decay),
                             fl(args.extent), fl(args.w_max), fl(args.oncoming_heat_thr), fl(args.oncoming_n),
                             fl(args.oncoming_extent), fl(args.oncoming_max_aspect), fl(args.motion))
    for thr, tw, ht, n, dc, ex, wm, wht, wn, wex, wma, mo in grid:
        heat = replace(h, threshold=ht, n_frames=int(n), decay=dc, extent=ex, w_max=wm, box_mode=args.box)
        wheat = replace(w, threshold=wht, n_frames=int(wn), extent=wex, max_aspect=wma, box_mode=args.oncoming_box)
        cells, f1s = [], []
        for name, (gt, clip) in caches.items():
            first = int(per_clip.get(name, args.first)) or len(clip) // 2 + 1
            preds = replay(clip, thr, heat, wheat, MotionGate(mo), tw, first, tracker=not args.no_track)
            r = evaluate_from(gt, preds, first, len(clip))
            cells.append(f"{r.precision:.2f} {r.recall:.2f} **{r.f1:.2f}** {r.ap:.2f} {r.fp_per_frame:.2f}")
            f1s.append(r.f1)
        oncoming_cell = f"{wht:g}/{int(wn)}/{wex:g}/{wma:g}" if det.oncoming_model is not None else "-"
        line = (f"| {thr:g} | {tw:g} | {ht:g} | {int(n)} | {dc:g} | {ex:g} | {wm:g} | {oncoming_cell} | {mo:g} | "
                + " | ".join(cells) + f" | {min(f1s):.3f} |")
        rows.append((min(f1s), line))
        print(line, flush=True)
    print("\nbest:")
    for _, line in sorted(rows, reverse=True)[:5]:
        print(line)


if __name__ == "__main__":
    main()

"""How the pipeline holds when the horizon is off: every annotated clip with its held-out box
regressor at the horizon estimate and at the estimate moved by a few hundredths of the height
(run by hand; docs/geometry.md "Tolerance").

For each clip and each offset ``D`` of ``--offsets`` the video pipeline (``fastdet eval --all``'s
run) runs with ``PipelineConfig(horizon=E + D)``, ``E`` the clip's horizon estimate
(:func:`fastdet.video.horizon.estimate_horizon` over its first frames; ``D = 0`` runs
``horizon='auto'``, the default pipeline); ``D > 0`` puts the horizon lower in the picture than
the estimate, ``D < 0`` higher. The box regressor is ``--loo DIR``'s ``refine_without_CLIP.npz``
(``python -m tools.studies.refine_loo --out-dir DIR``), so every figure is held out. Prints one
table (F1, P / R, false alarms a frame, recall by width per clip and offset) and the windows the
pipeline scored a frame (guided search and motion gate included); ``--out-dir`` keeps each
run's boxes (``TAG/CLIP_D.npz``: a :class:`~fastdet.detections.Detections` written by
:func:`~tools.studies.frame_cache.save_frame_detections`) and the results
(``TAG/results.json``; a rerun skips what is there with the same settings).

The settings varied (each a change of the main model's default search; slack below the
oncoming model's bands, once a third, was deleted: docs/accuracy.md, "Deleted stages"):

- ``--band-slack ABOVE,0``: the main bands' :attr:`~fastdet.config.SearchBand.slack_above`
  (every band with slack today; 0: none); slack below the bands was deleted, so the second
  number (kept for the commands written before) must be 0;
- ``--slack-threshold D``: the main search's ``slack_threshold`` (``nan``: none).

``--cost`` prints, instead of running, the HOG cells, windows and scoring multiply-adds of a
full scan of a 1280x720 frame at the reference horizon with the setting's searches, against
today's. ``--why D`` prints, for every target of ``--clips`` on the annotated frames (every
``--every``-th), whether the runs of ``--tag`` at the estimate and at ``D`` found it (IoU 0.5)
and each model's best window on it (IoU >= 0.4: decision value, whether it beats its row's
threshold, band scale, window bottom row / H) in the searches at ``E`` and at ``E + D`` and in
a dense search (every scale on every row of the lower part of the frame).

    python -m tools.studies.tolerance --loo /tmp/s3r/final --out-dir DIR [--clips A,B]
        [--offsets 0,-0.04,0.04] [--tag NAME] [--band-slack A,0] ...
    python -m tools.studies.tolerance --cost [--band-slack A,0] ...
    python -m tools.studies.tolerance --loo ... --out-dir DIR --tag NAME --why 0.04 --clips highway_640
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from fastdet.boxes import iou
from fastdet.config import PipelineConfig, SearchBand, SearchConfig, oncoming_search
from fastdet.detect import Detector, DetectStats
from fastdet.detect.bands import window_boxes
from fastdet.detect.geometry import row_thresholds
from fastdet.detections import Detections
from fastdet.eval.clips import AnnotatedClip, annotated_clips, markdown_table, score_clip
from fastdet.io.atomic import write_bytes
from fastdet.io.reader import FrameReader
from fastdet.video import make_detector
from fastdet.video.horizon import HORIZON_FRAMES, estimate_horizon
from fastdet.video.run import iter_video_detections
from tools.studies.band_cost import count_scored, scan_cost
from tools.studies.frame_cache import load_frame_detections, save_frame_detections
from tools.studies.loo import frame_rows

#: the horizon the runs take when a clip gives no estimate (the reference bands' horizon)
FALLBACK_HORIZON = 0.585


def clip_estimate(video: Path, n: int = HORIZON_FRAMES) -> float | None:
    """The horizon estimate of the video's first ``n`` frames (as the pipeline's ``'auto'``)."""
    r = FrameReader(str(video), notify=lambda _n: None)
    try:
        return estimate_horizon((f for _, f, _ in r), max_frames=n)
    finally:
        r.close()


def parse_slack(text: str) -> float | None:
    """``'ABOVE,0'`` (or ``'ABOVE'``) as the slack above (0: ``None``, none). A slack below the
    bands (the second number not 0) was deleted: one line, exit 2."""
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) not in (1, 2):
        raise SystemExit(f"--band-slack must be ABOVE or ABOVE,0 (fractions of the height), got {text!r}")
    if len(vals) == 2 and vals[1] != 0:
        raise SystemExit(f"--band-slack {text}: slack below the bands was deleted (docs/accuracy.md, "
                         "'Deleted stages'); only 0 is read there")
    return vals[0] or None


def searches(a: argparse.Namespace) -> tuple[SearchConfig, SearchConfig]:
    """The main search the options ask for (today's when they ask nothing) and the oncoming search."""
    main = PipelineConfig().search
    if a.band_slack is not None:
        above = parse_slack(a.band_slack)
        main = replace(main, bands=tuple(replace(b, slack_above=above) if b.has_slack else b for b in main.bands))
    if a.slack_threshold is not None:
        main = replace(main, slack_threshold=None if math.isnan(a.slack_threshold) else a.slack_threshold)
    return main, oncoming_search(PipelineConfig().traffic)


def detector(a: argparse.Namespace, config: PipelineConfig) -> Detector:
    """The pipeline's detector for ``config`` with the options' searches."""
    main, oncoming = searches(a)
    det = make_detector(replace(config, search=main))
    if len(det.scorers) > 1:
        det.scorers[1].search = replace(oncoming, horizon=det.scorers[1].search.horizon)
    return det


def run(clip: AnnotatedClip, horizon: float | Literal["auto"],
        a: argparse.Namespace) -> tuple[Detections, dict[str, Any]]:
    """The pipeline over ``clip`` at ``horizon`` with the held-out regressor and the options'
    searches: its boxes, the windows it scored a frame (main model, all models) and the
    multiply-adds of scoring them."""
    config = PipelineConfig(refine_model=str(Path(a.loo) / f"refine_without_{clip.name}.npz"), horizon=horizon)
    det = detector(a, config)
    counts = count_scored(det)
    frames = list(iter_video_detections(clip.video, config, detector=det, progress=False))
    preds = Detections.from_frames(frames, source=str(clip.video))
    n = max(len(frames), 1)
    return preds, {"main_windows": counts[0] / n, "windows": counts[1] / n, "score_macs": counts[2] / n}


def best_windows(det: Detector, frame: np.ndarray, box: np.ndarray) -> dict[int, tuple[float, bool, float, float]]:
    """Per model part, the window of ``det``'s full search of ``frame`` with IoU >= 0.4 with
    ``box`` and the highest decision value: ``(value, beats its row's threshold, band scale,
    window bottom row / H)``."""
    st = DetectStats()
    det.detect(frame, stats=st)
    out: dict[int, tuple[float, bool, float, float]] = {}
    for part, geo, dec in st.bands:
        sc = det.scorers[det.parts.index(part)]
        r, c = np.nonzero(np.isfinite(dec))
        if not len(r):
            continue
        b = window_boxes(geo, r, c, sc.config).astype(float)
        k = np.nonzero(iou(box[None].astype(float), b)[0] >= 0.4)[0]
        if not len(k):
            continue
        j = k[np.argmax(dec[r[k], c[k]])]
        v = float(dec[r[j], c[j]])
        thr = np.broadcast_to(row_thresholds(geo, sc.search, sc.config), (geo.ny,))[r[j]]
        if part not in out or v > out[part][0]:
            out[part] = (v, bool(v > thr), float(geo.band.scale), float(b[j, 3] / frame.shape[0]))
    return out


def dense(a: argparse.Namespace) -> Detector:
    """Every main scale on every row from 0.42 H down, every oncoming scale from 0.46 to 0.78 H
    (reference rows), no slack gate: where the models would find each target."""
    det = detector(a, PipelineConfig())
    main = det.scorers[0].search
    det.scorers[0].search = replace(main, slack_threshold=None, bands=tuple(
        SearchBand(b.scale, 300, 720) for b in main.bands))
    if len(det.scorers) > 1:
        on = det.scorers[1].search
        det.scorers[1].search = replace(on, bands=tuple(replace(b, y_start=330, y_stop=560) for b in on.bands))
    return det


def why(clip: AnnotatedClip, d: float, out: Path, a: argparse.Namespace) -> None:
    """Print what became of every target at the offset ``d`` (module docstring)."""
    key0, key1 = f"{clip.name}_{0.0:+.3f}", f"{clip.name}_{d:+.3f}"
    results = json.loads((out / "results.json").read_text())
    if key0 not in results or key1 not in results:
        raise SystemExit(f"tolerance: run {clip.name} at offsets 0 and {d:+.3f} with --tag {out.name} first")
    est = results[key0]["estimate"] or FALLBACK_HORIZON
    found = [load_frame_detections(out / f"{k}.npz")[0] for k in (key0, key1)]
    dets = []
    for h in (est, est + d):
        det = detector(a, PipelineConfig())
        det.set_horizon(h)
        dets.append(det)
    dets.append(dense(a))
    gt = clip.gt()
    keep = np.asarray(gt.consider, bool) if gt.consider is not None else np.ones(len(gt), bool)
    assert gt.frames is not None, "an annotation file gives every box its frame"
    frames = sorted({int(f) for f in gt.frames[keep]})
    kf = clip.keyframes()
    if kf is not None:
        frames = [f for f in frames if f in {int(k) for k in kf}]
    want = set(frames[::a.every])
    print(f"{clip.name}: estimate {est:.3f}, offset {d:+.3f}. Per target: frame, id, width (px of a 1280-wide "
          f"frame), bottom / H (from the estimate), found at the estimate / offset; then per search (at the "
          f"estimate | at the offset | dense) part: (decision value, beats its threshold, scale, window bottom / H)")
    r = FrameReader(str(clip.video), notify=lambda _n: None)
    try:
        for i, frame, _ in r:
            f = i + 1
            if f not in want:
                continue
            rows, cols = frame.shape[:2]
            m = (gt.frames == f) & keep
            for box, tid in zip(gt.boxes[m], gt.ids[m] if gt.ids is not None else np.zeros(m.sum())):
                hit = []
                for p in found:
                    assert p.frames is not None, "a run's boxes carry their frames"
                    pm = p.frames == f
                    hit.append(bool(pm.any() and iou(box[None].astype(float), p.boxes[pm].astype(float)).max() >= 0.5))
                flag = "LOST" if hit[0] and not hit[1] else ("GAINED" if hit[1] and not hit[0] else "")
                cells = []
                for det in dets:
                    bw = best_windows(det, frame, np.asarray(box))
                    cells.append(" ".join(f"{p}:({v:.2f},{'y' if ok else 'n'},{s:.2f},{y:.3f})"
                                          for p, (v, ok, s, y) in sorted(bw.items())) or "-")
                print(f"{f:4d} {int(tid):4d} w{(box[2] - box[0]) * 1280 / cols:4.0f} bottom {box[3] / rows:.3f} "
                      f"({box[3] / rows - est:+.3f}) {int(hit[0])}{int(hit[1])} {flag:6s} | " + " | ".join(cells),
                      flush=True)
    finally:
        r.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--loo", help="the held-out box regressors (refine_loo --out-dir)")
    ap.add_argument("--out-dir", type=Path)
    ap.add_argument("--tag", default="base", help="the setting's name in --out-dir")
    ap.add_argument("--clips", default=None)
    ap.add_argument("--offsets", default="0,-0.04,0.04", help="horizon offsets from the estimate (0: 'auto')")
    ap.add_argument("--band-slack", default=None, metavar="ABOVE,0")
    ap.add_argument("--slack-threshold", type=float, default=None)
    ap.add_argument("--cost", action="store_true", help="print the setting's full-scan cost against today's")
    ap.add_argument("--why", type=float, default=None, metavar="D", help="what became of each target at offset D")
    ap.add_argument("--every", type=int, default=1, help="--why: every this many annotated frames")
    a = ap.parse_args(argv)
    if a.every < 1:
        ap.error("--every must be >= 1")
    if a.cost:
        base, new = scan_cost(make_detector()), scan_cost(detector(a, PipelineConfig()))
        for k in base:
            print(f"{k}: {new[k]:.0f} against {base[k]:.0f} today ({new[k] / base[k]:.3f}x)")
        return 0
    if a.loo is None or a.out_dir is None:
        ap.error("--loo and --out-dir are needed unless --cost")
    out = a.out_dir / a.tag
    clips = annotated_clips()
    if a.clips:
        clips = [c for c in clips if c.name in a.clips.split(",")]
    if a.why is not None:
        for clip in clips:
            why(clip, a.why, out, a)
        return 0
    out.mkdir(parents=True, exist_ok=True)
    res_path = out / "results.json"
    results: dict[str, Any] = json.loads(res_path.read_text()) if res_path.is_file() else {}
    skip = ("out_dir", "clips", "offsets", "tag", "cost", "why", "every")
    settings = {k: v for k, v in vars(a).items() if k not in skip}
    if results.get("settings", settings) != settings:
        print(f"tolerance: {out} holds other settings; use another --tag", file=sys.stderr)
        return 2
    results["settings"] = settings
    offsets = [float(v) for v in a.offsets.split(",")]
    scores = []
    for clip in clips:
        est = clip_estimate(clip.video)
        for d in offsets:
            key = f"{clip.name}_{d:+.3f}"
            boxes_path = out / f"{key}.npz"
            if key in results and boxes_path.is_file():
                preds = load_frame_detections(boxes_path)[0]
                extra = results[key]
            else:
                start = est if est is not None else FALLBACK_HORIZON
                horizon: float | Literal["auto"] = "auto" if d == 0 else min(max(start + d, 0.0), 1.0)
                preds, extra = run(clip, horizon, a)
                extra.update(estimate=est, offset=d, horizon=horizon)
                save_frame_detections(boxes_path, [preds])
            s = score_clip(f"{clip.name} {d:+.2f}", clip.gt(), preds, frame_rows(clip), clip.keyframes())
            extra.update(f1=s.result.f1, precision=s.result.precision, recall=s.result.recall,
                         fp_per_frame=s.result.fp_per_frame)
            results[key] = extra
            write_bytes(res_path, json.dumps(results, indent=1).encode())
            scores.append(s)
            print(f"{key}: F1 {s.result.f1:.3f} (horizon {extra['horizon']}, estimate {est}) windows a frame: main "
                  f"{extra['main_windows']:.0f}, all {extra['windows']:.0f}", flush=True)
    print(markdown_table(scores))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The main model's operating point set from each video itself (:mod:`fastdet.video.selfcal`),
measured leave one camera out on the five annotated clips (docs/training.md, "Operating point
from the video itself").

1. **The tails.** Per clip, the decision values of every main-model window of the pipeline's
   full scans (frames 1, 6, 11, ...: the guided search's), with the bands at the horizon the
   pipeline primes for the clip, by the bundled model and by each held-out model of the clip's
   fold (``WORK/main[_TAG]_without_FOLD.npz``, trained without the clip's camera: model_loo);
   the value a fraction r of the windows exceeds, over the first 25 / 50 / 100 frames (is it
   stable?), per model (does it separate the cameras?).
2. **The rule.** :class:`~fastdet.config.SelfCalibration`: the offset is ``q - level``, ``q`` the
   value ``rate`` of the windows of the first ``scans`` full scans exceed; ``level`` for a clip
   is learnt only from the *other* cameras: the median over them of the bundled model's ``q``
   (each camera's windows pooled; the two Udacity clips are one camera). The offsets it gives.
3. **The pipeline.** Every clip scored (keyframes, IoU 0.5) by the bundled model, the held-out
   model and their 0.5 blend (:func:`fastdet.train.blend.blend`), each without and with the
   per-video offset (``PipelineConfig(selfcal=SelfCalibration(level=level of the clip))``), with
   the box regressor fitted without the clip (``--refine-loo DIR``:
   ``DIR/refine_without_CLIP.npz``, ``python -m tools.studies.refine_loo``).
4. ``--sweep D1,D2,...`` (a bound, not a rule: the offsets are chosen by looking at the scored
   clips): the bundled and the held-out model with each fixed offset
   (:func:`fastdet.train.blend.offset`), so the best F1 any per-video offset could give each clip.

Usage (from the repository root; about 5 minutes)::

    python -m tools.studies.selfcal --work /tmp/s5-selfcal/loo --refine-loo /tmp/s5-selfcal/refine_final \\
        [--cache DIR] [--rate 0.1] [--scans 5] [--tags ,r2,sq,light] [--no-pipeline] [--sweep D1,D2,...]
        [--json OUT]
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from fastdet.config import PipelineConfig, SelfCalibration
from fastdet.detect import Detector
from fastdet.eval.clips import ClipScore, annotated_clips
from fastdet.io.atomic import write_bytes
from fastdet.io.reader import FrameReader
from fastdet.model import Model, load_model
from fastdet.train.blend import blend, offset
from fastdet.video.pipeline import VideoDetector
from fastdet.video.run import prime_horizon_from_file
from fastdet.video.selfcal import SelfCalStage, calibration_offset
from tools.studies.loo import folds, run_clip

#: frames over which the tail's stability is measured
SPANS = (25, 50, 100)
#: fractions of the windows whose value is reported
RATES = (0.01, 0.03, 0.1, 0.3)
ORDER = ("test_small1", "test_video", "highway_640", "boston_street", "motorcycle_highway")


def clip_horizon(video: Path, config: PipelineConfig) -> float | None:
    """The horizon the pipeline primes for ``video`` (fraction of the height; ``None``: reference)."""
    vd = VideoDetector(config=replace(config, selfcal=None))
    prime_horizon_from_file(vd, str(video))
    return vd.detector.horizon


def full_scan_frames(video: Path, frames: int, every: int) -> list[tuple[int, np.ndarray]]:
    """``(frame number, BGR frame)`` of frames 1, 1 + every, ... up to ``frames``."""
    out = []
    reader = FrameReader(str(video), 0, frames, notify=lambda _n: None)
    try:
        for fno, frame, _ in reader:
            if (fno - 1) % every == 0:
                out.append((int(fno), np.array(frame)))
    finally:
        reader.close()
    return out


def scan_values(model: Model, frames: list[tuple[int, np.ndarray]], config: PipelineConfig,
                horizon: float | None) -> tuple[np.ndarray, np.ndarray]:
    """``(values, counts)``: every main-band window's decision value, frame after frame
    (concatenated; ``counts`` per frame)."""
    det = Detector(model=model, search=config.search, horizon=horizon)
    vals, counts = [], []
    for _, f in frames:
        v = np.concatenate([det.band_scores(f, g).ravel() for g in det.geometries(f.shape[:2], 0)])
        v = v[np.isfinite(v)]
        vals.append(v.astype(np.float32))
        counts.append(len(v))
    return np.concatenate(vals), np.asarray(counts, np.int64)


def clip_tails(cache: Path, clip, models: dict[str, Model], config: PipelineConfig, every: int) -> dict[str, Any]:
    """Per model, the decision values of the clip's full scans over its first max(SPANS) frames
    (``{tag: (values, counts)}``, ``frames``), cached in ``cache/CLIP.npz`` (a model missing there
    is scored and the file rewritten)."""
    path = cache / f"{clip.name}.npz"
    have: dict[str, np.ndarray] = {}
    if path.is_file():
        with np.load(path, allow_pickle=False) as z:
            have = {k: z[k] for k in z.files}
    missing = [t for t in models if f"{t}_values" not in have]
    if missing:
        h = clip_horizon(clip.video, config)
        fr = full_scan_frames(clip.video, max(SPANS), every)
        have["frames"] = np.asarray([n for n, _ in fr], np.int64)
        for t in missing:
            have[f"{t}_values"], have[f"{t}_counts"] = scan_values(models[t], fr, config, h)
        tmp = path.with_name(path.stem + ".tmp.npz")
        np.savez(tmp, **have)
        tmp.replace(path)
    return {"frames": have["frames"], **{t: (have[f"{t}_values"], have[f"{t}_counts"]) for t in models}}


def first(values: np.ndarray, counts: np.ndarray, n_scans: int) -> np.ndarray:
    """The values of the first ``n_scans`` full scans."""
    return values[: int(counts[:n_scans].sum())].astype(np.float64)


def quantile_at(values: np.ndarray, rate: float) -> float:
    """The value a fraction ``rate`` of ``values`` exceeds (as :func:`calibration_offset` finds it)."""
    return float(np.quantile(values, 1.0 - rate))


def cell(s: ClipScore) -> str:
    r = s.result
    fa = r.fp_per_frame
    widths = " ".join(f"{b.found}/{b.total}" for b in s.widths if b.total)
    p = "n/a" if not np.isfinite(r.precision) else f"{r.precision:.2f}"
    return f"{r.f1:.2f} ({p} / {r.recall:.2f}, {fa:.2f}; {widths})"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="the held-out main models (model_loo --work)")
    ap.add_argument("--refine-loo", type=Path, required=True, help="DIR/refine_without_CLIP.npz (refine_loo)")
    ap.add_argument("--cache", type=Path, default=None, help="the tails' cache (default WORK/selfcal_tails)")
    ap.add_argument("--rate", type=float, default=SelfCalibration.rate)
    ap.add_argument("--scans", type=int, default=SelfCalibration.scans)
    ap.add_argument("--tags", default=",r2,sq,light", help="held-out recipes whose tails to report "
                                                          "(the first one's model is scored in the pipeline)")
    ap.add_argument("--mix", type=float, default=0.5, help="the held-out model's weight in the blend scored")
    ap.add_argument("--no-pipeline", action="store_true", help="only the tails and offsets")
    ap.add_argument("--sweep", default=None, help="instead of the pipeline rows: fixed offsets D1,D2,... of the "
                                                   "bundled and the held-out model (a bound, in-sample)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    if not 0 < args.rate < 1 or args.scans < 1 or not 0 <= args.mix <= 1:
        ap.error("--rate in (0, 1), --scans >= 1, --mix in [0, 1]")
    config = PipelineConfig()
    every = config.planned.every if config.planned is not None else 1
    cache = args.cache or args.work / "selfcal_tails"
    cache.mkdir(parents=True, exist_ok=True)
    clips = {c.name: c for c in annotated_clips()}
    names = [n for n in ORDER if n in clips] + sorted(set(clips) - set(ORDER))
    fold_of = {n: f for f in folds(names) for n in f.held_out}
    bundled = load_model(None)
    tags = [t.strip() for t in args.tags.split(",")]
    out: dict[str, Any] = {"rate": args.rate, "scans": args.scans, "clips": {}}

    # 1. the tails
    tails: dict[str, dict[str, Any]] = {}
    for n in names:
        fold = fold_of[n].name
        held = {f"main{'_' + t if t else ''}": load_model(args.work / f"main{'_' + t if t else ''}_without_{fold}.npz")
                for t in tags}
        tails[n] = clip_tails(cache, clips[n], {"bundled": bundled, **held}, config, every)
        b, h = tails[n]["bundled"], tails[n][next(iter(held))]
        tails[n]["mix"] = ((1 - args.mix) * b[0] + args.mix * h[0], b[1])  # one linear model: values mix
    model_tags = ["bundled", *(f"main{'_' + t if t else ''}" for t in tags), "mix"]
    print(f"## 1. Decision value a fraction of the full-scan windows exceeds (r = {', '.join(map(str, RATES))}),"
          f" first {args.scans} full scans; r = {args.rate} over the first {' / '.join(map(str, SPANS))} frames\n")
    print("| clip | windows / scan | model | " + " | ".join(f"r={r:g}" for r in RATES) + " | "
          + " | ".join(f"r={args.rate:g}, {s} frames" for s in SPANS) + " |")
    print("|---|---|---|" + "---|" * (len(RATES) + len(SPANS)))
    for n in names:
        fr = tails[n]["frames"]
        for t in model_tags:
            v, c = tails[n][t]
            head = first(v, c, args.scans)
            row = [quantile_at(head, r) for r in RATES]
            span = [quantile_at(first(v, c, int((fr <= s).sum())), args.rate) for s in SPANS]
            out["clips"].setdefault(n, {}).setdefault("tail", {})[t] = {"q": row, "spans": span,
                                                                        "windows_per_scan": float(c.mean())}
            print(f"| {n} | {c.mean():.0f} | {t} | " + " | ".join(f"{x:+.2f}" for x in row) + " | "
                  + " | ".join(f"{x:+.2f}" for x in span) + " |")

    # 2. the rule: each clip's level from the other cameras' bundled tails
    cams = [f.held_out for f in folds(names)]
    cam_q = {cam: quantile_at(np.concatenate([first(*tails[n]["bundled"], args.scans) for n in cam]), args.rate)
             for cam in cams}
    print(f"\n## 2. Each camera's bundled q (r = {args.rate}, first {args.scans} full scans): "
          + ", ".join(f"{'+'.join(c)} {q:+.2f}" for c, q in cam_q.items())
          + f"; all cameras' median {float(np.median(list(cam_q.values()))):+.2f}\n")
    out["camera_q"] = {"+".join(c): q for c, q in cam_q.items()}
    out["level_all"] = float(np.median(list(cam_q.values())))
    print("| clip | level (other cameras) | " + " | ".join(f"offset {t}" for t in model_tags) + " |")
    print("|---|---|" + "---|" * len(model_tags))
    levels = {}
    for n in names:
        cam = fold_of[n].held_out
        level = float(np.median([q for c, q in cam_q.items() if c != cam]))
        levels[n] = level
        sc = SelfCalibration(scans=args.scans, rate=args.rate, level=level)
        offs = {t: calibration_offset(first(*tails[n][t], args.scans), sc) for t in model_tags}
        out["clips"][n].update(level=level, offsets=offs)
        print(f"| {n} | {level:+.2f} | " + " | ".join(f"{offs[t]:+.2f}" for t in model_tags) + " |")
    if args.no_pipeline:
        if args.json:
            write_bytes(args.json, json.dumps(out, indent=1, sort_keys=True).encode())
        return 0

    main_tag = f"main{'_' + tags[0] if tags[0] else ''}"
    if args.sweep:
        return sweep(args, names, clips, fold_of, bundled, main_tag, out)

    # 3. the pipeline
    rows: dict[str, dict[str, str]] = {}
    for n in names:
        fold = fold_of[n].name
        held_path = args.work / f"{main_tag}_without_{fold}.npz"
        mix_path = args.work / f"{main_tag}_mix{args.mix:g}_without_{fold}.npz"
        if not mix_path.is_file():
            blend([bundled, load_model(held_path)], [1 - args.mix, args.mix]).save(mix_path)
        refine = args.refine_loo / f"refine_without_{n}.npz"
        if not refine.is_file():
            print(f"selfcal: {refine} missing", file=sys.stderr)
            return 2
        base = PipelineConfig(refine_model=str(refine))
        sc = SelfCalibration(scans=args.scans, rate=args.rate, level=levels[n])
        for label, path in (("bundled", None), (main_tag, held_path), (f"mix {args.mix:g}", mix_path)):
            for cal in (False, True):
                cfg = replace(base, model=None if path is None else str(path), selfcal=sc if cal else None)
                score = run_clip(clips[n], cfg)
                name = label + (", self-calibrated" if cal else "")
                offset = None
                if cal:  # the offset in force in that run (the stage's own estimate)
                    vd = VideoDetector(config=cfg)
                    prime_horizon_from_file(vd, str(clips[n].video))
                    st = vd.stage(SelfCalStage)
                    offset = st.offset if isinstance(st, SelfCalStage) else None
                rows.setdefault(name, {})[n] = cell(score) + ("" if offset is None else f" [{offset:+.2f}]")
                out["clips"][n].setdefault("pipeline", {})[name] = {**score.to_dict(), "offset": offset}
                print(f"{n}: {name}: {rows[name][n]}", flush=True)
    print("\n## 3. Pipeline, leave one camera out: F1 (P / R, FA per frame; hits by width < 60 / 60-120 / >= 120 "
          "px of 1280) [offset]\n")
    print("| model scored | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for name, r in rows.items():
        print(f"| {name} | " + " | ".join(r.get(n, "-") for n in names) + " |")
    if args.json:
        write_bytes(args.json, json.dumps(out, indent=1, sort_keys=True, default=float).encode())
    return 0


def sweep(args: argparse.Namespace, names: list[str], clips: dict, fold_of: dict, bundled: Model, main_tag: str,
          out: dict[str, Any]) -> int:
    """4.: every clip by the bundled and the held-out model, each with every fixed offset of ``--sweep``."""
    deltas = [float(d) for d in args.sweep.split(",")]
    table: dict[str, dict[float, dict[str, str]]] = {}
    for n in sorted(names, key=lambda c: c.startswith("test_")):  # the other cameras first
        fold = fold_of[n].name
        base = PipelineConfig(refine_model=str(args.refine_loo / f"refine_without_{n}.npz"))
        held = load_model(args.work / f"{main_tag}_without_{fold}.npz")
        for label, model in (("bundled", bundled), (main_tag, held)):
            for d in deltas:
                path = args.work / f"sweep_{label}_off{d:g}_without_{fold}.npz"
                if not path.is_file():
                    offset(model, d, {"fixed_offset": d}).save(path)
                score = run_clip(clips[n], replace(base, model=str(path)))
                r = score.result
                table.setdefault(label, {}).setdefault(d, {})[n] = f"{r.f1:.2f} ({r.fp_per_frame:.2f})"
                out["clips"].setdefault(n, {}).setdefault("sweep", {}).setdefault(label, {})[str(d)] = score.to_dict()
                print(f"{n}: {label} offset {d:+g}: {cell(score)}", flush=True)
    for label, rows in table.items():
        print(f"\n## 4. {label} with a fixed offset: F1 (FA per frame), leave one camera out\n")
        print("| offset | " + " | ".join(names) + " |")
        print("|---|" + "---|" * len(names))
        for d in deltas:
            print(f"| {d:+g} | " + " | ".join(rows[d].get(n, "-") for n in names) + " |")
    if args.json:
        write_bytes(args.json, json.dumps(out, indent=1, sort_keys=True, default=float).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())

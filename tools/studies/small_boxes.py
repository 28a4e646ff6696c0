"""How well the boxes fit the vehicles, per clip and by width, and what the false alarms are
(run by hand; docs/geometry.md "Small vehicles").

Runs the video pipeline (the one ``fastdet eval --all`` runs) on every annotated clip and,
on the scored frames (keyframes, or every annotated frame), measures for every target
(``consider`` = 1), binned by width in reference pixels (< 60, 60-120, >= 120):

- ``det``: a returned box with IoU >= 0.3 with it; the median IoU, height ratio (box / target)
  and width ratio of the best such box; ``hit``: matched at IoU 0.5 (as eval matches);
- ``heat``: the same for the heat maps' boxes before the tracker (``FrameDebug.boxes``);
- ``win``: main-model windows with IoU >= 0.3 per target, and the target's peak heat
  (the main heat map's largest cell inside the target box; threshold 4 by default);

and every false alarm (a returned box neither matched at 0.5 nor on an ignore region) as a
*near miss* (IoU 0.3-0.5 with a target: a true detection with a bad box) or *far* (< 0.3).

Settings (the pipeline's defaults otherwise): ``--heat key=value`` (HeatConfig fields, e.g.
``--heat extent=0.5``), ``--no-refine``, ``--no-split`` (the neighbour split off; ``--split``, on, is the
default), ``--no-track``.
Prints the per-clip table of ``fastdet eval --all`` and the measurement tables.

    python -m tools.studies.small_boxes [--clips A,B] [--heat k=v ...] [--no-refine] [--json OUT]
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import fields, replace
from typing import Any

import numpy as np

from fastdet.boxes import iou as box_iou
from fastdet.config import HeatConfig, NeighbourSplit, PipelineConfig, RefineConfig, TrackerConfig
from fastdet.detect.bands import window_boxes
from fastdet.detect.detector import DetectStats
from fastdet.detections import MAIN_PART, Detections
from fastdet.eval.clips import annotated_clips, markdown_table, score_clip
from fastdet.eval.matching import match_frame
from fastdet.io.reader import FrameReader
from fastdet.video.detector import make_detector
from fastdet.video.run import video_detector_for
from tools.studies.markdown import table

BINS = ((0.0, 60.0, "<60"), (60.0, 120.0, "60-120"), (120.0, float("inf"), ">=120"))


def _value(s: str) -> Any:
    for cast in (int, float):
        try:
            return cast(s)
        except ValueError:
            pass
    return {"none": None, "true": True, "false": False}.get(s.lower(), s)


def overrides(items: list[str] | None, cls: type, flag: str) -> dict[str, Any]:
    """``KEY=VALUE`` options naming fields of the dataclass ``cls``, as keyword arguments."""
    names = {f.name for f in fields(cls)}
    kw = {}
    for item in items or ():
        k, v = item.split("=", 1)
        if k not in names:
            raise SystemExit(f"{flag}: {cls.__name__} has no field {k!r}")
        kw[k] = _value(v)
    return kw


def config_from(args: argparse.Namespace) -> PipelineConfig:
    heat = replace(HeatConfig(), **overrides(args.heat, HeatConfig, "--heat"))
    cfg = PipelineConfig(heat=heat, refine_model=args.refine_model, model=args.model,
                         oncoming=args.oncoming_model if args.oncoming_model is not None else True)
    rkw = overrides(args.refine, RefineConfig, "--refine")
    if rkw:
        cfg = replace(cfg, refine=replace(RefineConfig(), **rkw))
    if args.no_refine:
        cfg = replace(cfg, refine=None)
    if args.split:
        cfg = replace(cfg, split=NeighbourSplit())
    if args.no_split:
        cfg = replace(cfg, split=None)
    skw = overrides(getattr(args, "split_opt", None), NeighbourSplit, "--split-opt")
    if skw and cfg.split is not None:
        cfg = replace(cfg, split=replace(cfg.split, **skw))
    tkw = overrides(getattr(args, "tracker_opt", None), TrackerConfig, "--tracker-opt")
    if tkw and cfg.tracker is not None:
        cfg = replace(cfg, tracker=replace(cfg.tracker, **tkw))
    if args.no_track:
        cfg = replace(cfg, tracker=None, guided=None)
    return cfg


def searched_windows(det, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every window the main model's full search scores on ``frame``, positive or not:
    ``(boxes (N, 4) float64, decision values (N,))`` (one more full detection of the frame)."""
    st = DetectStats()
    det.detect(frame, stats=st)
    boxes, decs = [], []
    for part, geo, dec in st.bands:
        if part != MAIN_PART:
            continue
        r, c = np.nonzero(np.isfinite(dec))
        boxes.append(window_boxes(geo, r, c, det.scorers[0].config).astype(np.float64))
        decs.append(dec[r, c])
    if not boxes:
        return np.zeros((0, 4)), np.zeros(0)
    return np.concatenate(boxes), np.concatenate(decs)


def run_clip(clip, config: PipelineConfig, search: bool = False) -> tuple[list, list, int, dict]:
    """The pipeline over one clip: ``(frames [(fno, out)], records {fno: ...}, rows, counts)``;
    records only for the scored frames, with the horizon the search used (with ``search``, also
    every window the main model's full search scores there, :func:`searched_windows`)."""
    gt, kf = clip.gt(), clip.keyframes()
    scored = set(int(f) for f in (kf if kf is not None else np.unique(gt.frames)))
    reader = FrameReader(str(clip.video), notify=lambda _n: None)
    frames, rec = [], {}
    n_windows = 0
    cpu0 = None
    try:
        det = make_detector(config)
        vd = video_detector_for(reader, det, config)
        vd.warmup()
        for fno, frame, _ in reader:
            out = vd.update(frame)
            if cpu0 is None:
                cpu0 = time.process_time()
            frames.append((fno, out))
            dbg = vd.debug
            w = dbg.windows
            n_windows += len(w)
            if fno in scored:
                main = w[w.part == MAIN_PART] if w.part is not None else w
                rec[fno] = dict(out=out, boxes=dbg.boxes, windows=main, heat=dbg.heat.copy(),
                                horizon=getattr(vd.detector, "horizon", None))
                if search:
                    rec[fno]["searched"] = searched_windows(vd.detector, frame)
        rows = reader.shape[0]
    finally:
        reader.close()
    cpu = (time.process_time() - cpu0) / max(len(frames) - 1, 1) if cpu0 is not None else float("nan")
    return frames, rec, rows, {"windows_per_frame": n_windows / max(len(frames), 1), "cpu_s_per_frame": cpu,
                               "cell": config.heat.cell}


def measure(clip, rec: dict, rows: int, cell: int) -> dict:
    """Per-target and per-false-alarm measurements (module docstring)."""
    gt = clip.gt()
    factor = 720.0 / rows
    targets, fas = [], []
    for fno, r in sorted(rec.items()):
        g = np.flatnonzero(gt.frames == fno)
        tb = gt.boxes[g[gt.consider[g]]]
        ib = gt.boxes[g[~gt.consider[g]]]
        out = r["out"]
        tp, dropped, gi = match_frame(out.boxes, out.scores, tb, ib, 0.5)
        hit = np.zeros(len(tb), bool)
        hit[gi[tp]] = True
        for name, d in (("det", out), ("heat", r["boxes"])):
            r[name + "_iou"] = box_iou(tb, d.boxes.astype(np.float64)) if len(d) and len(tb) else np.zeros((len(tb), 0))
        wins = r["windows"]
        wiou = box_iou(tb, wins.boxes.astype(np.float64)) if len(wins) and len(tb) else np.zeros((len(tb), 0))
        heat = r["heat"]
        for j, t in enumerate(tb):
            wref = (t[2] - t[0]) * factor
            row: dict[str, Any] = {"frame": fno, "w": wref, "h": (t[3] - t[1]) * factor, "hit": bool(hit[j])}
            for name, d in (("det", out), ("heat", r["boxes"])):
                m = r[name + "_iou"][j] if r[name + "_iou"].shape[1] else np.zeros(0)
                k = int(np.argmax(m)) if len(m) else -1
                if k >= 0 and m[k] >= 0.3:
                    b = d.boxes[k].astype(np.float64)
                    row[name] = {"iou": float(m[k]), "hr": float((b[3] - b[1]) / (t[3] - t[1])),
                                 "wr": float((b[2] - b[0]) / (t[2] - t[0])),
                                 "dy": float(((b[1] + b[3]) - (t[1] + t[3])) / 2 / (t[3] - t[1]))}
            wm = wiou[j] if wiou.shape[1] else np.zeros(0)
            row["win"] = int((wm >= 0.3).sum())
            row["win_best"] = float(wm.max()) if len(wm) else 0.0
            y0, y1 = int(t[1] // cell), int(np.ceil(t[3] / cell))
            x0, x1 = int(t[0] // cell), int(np.ceil(t[2] / cell))
            sub = heat[max(y0, 0):y1, max(x0, 0):x1]
            row["peak"] = float(sub.max()) if sub.size else 0.0
            if "searched" in r:  # any window of the full search, positive or not
                sb, sd = r["searched"]
                si = box_iou(t[None], sb)[0] if len(sb) else np.zeros(0)
                row["search_best_iou"] = float(si.max()) if len(si) else 0.0
                row["search_best_dec"] = float(sd[si >= 0.3].max()) if (si >= 0.3).any() else None
            targets.append(row)
        fa = ~tp & ~dropped
        dio = r["det_iou"]
        for k in np.flatnonzero(fa):
            best = float(dio[:, k].max()) if dio.shape[0] else 0.0
            b = out.boxes[k]
            j = int(np.argmax(dio[:, k])) if dio.shape[0] else -1
            item = {"frame": fno, "iou": best, "w": float((b[2] - b[0]) * factor), "h": float((b[3] - b[1]) * factor)}
            if j >= 0 and best >= 0.3:
                t = tb[j]
                item["hr"] = float((b[3] - b[1]) / (t[3] - t[1]))
                item["wr"] = float((b[2] - b[0]) / (t[2] - t[0]))
                item["tw"] = float((t[2] - t[0]) * factor)
            fas.append(item)
    return {"targets": targets, "fas": fas}


def _med(v: list[float]) -> str:
    return f"{np.median(v):.2f}" if v else "-"


def summary(name: str, m: dict) -> list[str]:
    lines = []
    for lo, hi, lab in BINS:
        ts = [t for t in m["targets"] if lo <= t["w"] < hi]
        if not ts:
            continue
        det = [t["det"] for t in ts if "det" in t]
        heat = [t["heat"] for t in ts if "heat" in t]
        lines.append(
            f"| {name} | {lab} | {len(ts)} | {sum(t['hit'] for t in ts)} | {len(det)} | "
            f"{_med([d['iou'] for d in det])} | "
            f"{_med([d['hr'] for d in det])} | {_med([d['wr'] for d in det])} | {_med([d['dy'] for d in det])} | "
            f"{len(heat)} | {_med([d['hr'] for d in heat])} | {_med([d['wr'] for d in heat])} | "
            f"{sum(t['win'] > 0 for t in ts)} | {_med([t['win'] for t in ts])} | {_med([t['peak'] for t in ts])} |")
    return lines


def search_summary(name: str, m: dict) -> list[str]:
    """Per width bin: targets some searched window overlaps at IoU >= 0.3, at >= 0.5, and those
    whose best decision value there is positive (``--search``)."""
    lines = []
    for lo, hi, lab in BINS:
        ts = [t for t in m["targets"] if lo <= t["w"] < hi and "search_best_iou" in t]
        if not ts:
            continue
        decs = [t["search_best_dec"] for t in ts if t["search_best_dec"] is not None]
        lines.append(f"| {name} | {lab} | {len(ts)} | {sum(t['search_best_iou'] >= 0.3 for t in ts)} | "
                     f"{sum(t['search_best_iou'] >= 0.5 for t in ts)} | {sum(d > 0 for d in decs)} | {_med(decs)} |")
    return lines


def fa_summary(name: str, m: dict, frames: int) -> str:
    fas = m["fas"]
    near = [f for f in fas if f["iou"] >= 0.3]
    tall = sum(1 for f in near if f["hr"] > 1.3)
    wide = sum(1 for f in near if f["wr"] > 1.3)
    small = sum(1 for f in near if f["wr"] < 1.3 and f["hr"] < 1.3)
    return (f"| {name} | {len(fas)} | {len(near)} | {tall} | {wide} | {small} | {len(fas) - len(near)} | "
            f"{_med([f['hr'] for f in near])} | {_med([f['wr'] for f in near])} |")


def add_setting_arguments(ap: argparse.ArgumentParser) -> None:
    """The pipeline settings this study varies (module docstring)."""
    ap.add_argument("--heat", action="append", metavar="KEY=VALUE", help="a HeatConfig field")
    ap.add_argument("--no-refine", action="store_true")
    ap.add_argument("--refine", action="append", metavar="KEY=VALUE", help="a RefineConfig field")
    ap.add_argument("--refine-model", default=None, help="the box regressor file (default: the bundled one)")
    ap.add_argument("--model", default=None, help="the main model file (default: the bundled one)")
    ap.add_argument("--oncoming-model", default=None,
                    help="the oncoming-traffic (wide-window) model file (default: the bundled one)")
    split = ap.add_mutually_exclusive_group()
    split.add_argument("--split", action="store_true", help="the neighbour split on (the default)")
    split.add_argument("--no-split", action="store_true", help="the neighbour split off")
    ap.add_argument("--split-opt", action="append", metavar="KEY=VALUE", help="a NeighbourSplit field")
    ap.add_argument("--tracker-opt", action="append", metavar="KEY=VALUE", help="a TrackerConfig field")
    ap.add_argument("--no-track", action="store_true")


def print_tables(tables: list[str], fa_lines: list[str], search_lines: list[str] | None = None) -> None:
    print()
    print(table("| clip | width | targets | hit@0.5 | det IoU>=0.3 | IoU | h ratio | w ratio | dy/h | heat IoU>=0.3 "
                "| heat h ratio | heat w ratio | with a window IoU>=0.3 | windows (median) | peak heat (median) |",
                tables))
    print()
    print(table("| clip | false alarms | near (IoU 0.3-0.5) | near, too tall (h > 1.3x) | near, too wide | "
                "near, other | far | near h ratio | near w ratio |", fa_lines))
    if search_lines:
        print()
        print(table("| clip | width | targets | searched window IoU >= 0.3 | IoU >= 0.5 | one of those positive | "
                    "best decision value there (median) |", search_lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", default=None)
    add_setting_arguments(ap)
    ap.add_argument("--json", default=None, help="write every measurement to this JSON file")
    ap.add_argument("--search", action="store_true",
                    help="also: does the main model's full search reach each target, with what decision value")
    args = ap.parse_args()
    config = config_from(args)
    clips = annotated_clips()
    if args.clips:
        want = args.clips.split(",")
        clips = [c for c in clips if c.name in want]
    scores, tables, fa_lines, search_lines, dump = [], [], [], [], {}
    for clip in clips:
        frames, rec, rows, counts = run_clip(clip, config, args.search)
        preds = Detections.from_frames(frames, source=str(clip.video))
        scores.append(score_clip(clip.name, clip.gt(), preds, rows, clip.keyframes()))
        m = measure(clip, rec, rows, int(config.heat.cell))
        tables += summary(clip.name, m)
        fa_lines.append(fa_summary(clip.name, m, len(rec)))
        search_lines += search_summary(clip.name, m)
        dump[clip.name] = {**m, **counts}
        print(f"{clip.name}: {counts['windows_per_frame']:.1f} positive windows a frame, "
              f"{counts['cpu_s_per_frame'] * 1e3:.0f} ms CPU a frame (not comparable on a loaded machine)", flush=True)
    print(markdown_table(scores))
    print_tables(tables, fa_lines, search_lines)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dump, f, indent=1)


if __name__ == "__main__":
    main()

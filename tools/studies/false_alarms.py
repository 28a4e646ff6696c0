"""Every false alarm of the video pipeline on the annotated clips, measured (run by hand;
docs/accuracy.md "False alarms on the new cameras").

Runs the pipeline (the defaults of ``fastdet eval --all``; ``--no-plausible``: without the
stage of :mod:`fastdet.video.plausible`; ``--loo-dir DIR``: each clip with the box regressor that never saw it, as
:mod:`tools.studies.refine_loo` fits them) over every annotated clip and, for
every box it returns on a scored frame (the keyframes of a keyframe clip, else every
annotated frame), records what ``fastdet eval`` makes of it (matched at IoU 0.5: a *hit*; more
than half on an ignore region: *ignored*; else a *false alarm*) and, for a false alarm,
whether it touches a target (*near*: too big or small, over two vehicles, on half a truck) or
no annotated box at all (*clear*), as :func:`tools.studies.loo.misplaced` splits them.

Per box: its width in reference pixels (the frame scaled to 720 rows), the pipeline's horizon
(``horizon``: the row the search bands are placed at, a fraction of the height), how far its
bottom edge is below that horizon (``dy``, fraction of the height; negative: above it), the
perspective ratio ``width / (bottom - horizon)`` (both in pixels; ``None`` for a bottom at or
above the horizon), its aspect (width / height), score (the heat map's peak), the frames its
track had been returned for up to this frame (``age``) and in the whole clip (``life``), whether
it touches the frame's left / right edge. Also every target's ratio, the range the filter
must keep.

    python -m tools.studies.false_alarms [--clips A,B] [--no-plausible] [--loo-dir DIR]
        [--rules] [--json OUT] [--crops DIR]

``--rules`` then applies each rule of :data:`RULES` (tried as a last stage: duplicates, the
perspective test at several bounds, boxes kept by weak blobs, the oncoming model's boxes, a
minimum track age) to the boxes of the same runs and prints, per clip, the false alarms, the hits
and the hits lost (targets matched before and not after, same frame, IoU 0.5).

``--crops DIR`` writes one picture per clip (``DIR/CLIP_fa.png``) of every false alarm's
surroundings, with the box (red), the targets (green), the ignore regions (grey) and the
horizon (blue line).
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fastdet.boxes import intersection, overlap_fraction
from fastdet.config import REFERENCE_HORIZON, PipelineConfig
from fastdet.detections import Detections
from fastdet.eval.clips import AnnotatedClip, annotated_clips, markdown_table, score_clip
from fastdet.eval.matching import match_frame
from fastdet.io.atomic import write_bytes
from fastdet.io.reader import FrameReader, read_frames_at
from fastdet.video.detector import make_detector
from fastdet.video.pipeline import VideoDetector
from fastdet.video.plausible import duplicates
from fastdet.video.run import video_detector_for
from tools.studies.markdown import table

REF_ROWS = 720


def _sources(vd: VideoDetector) -> dict[int, str]:
    """Where each track matched on this frame got its box: ``'main'`` (the main heat map),
    ``'oncoming'`` (the oncoming model's), ``'weak'`` (a low-confidence box), ``'other'``
    (a box the tracker cut between two tracks)."""
    if vd.tracker is None:
        return {}
    tables = [("weak", vd.debug.low.boxes)]
    for name, hm in (("main", vd.heatmap), ("oncoming", vd.oncoming_heatmap)):
        if hm is not None:
            tables.append((name, hm.blobs.boxes[hm.shape_ok(hm.blobs.boxes)]))
    out = {}
    for t in vd.tracker.tracks:
        if t.last_frame != vd.tracker.frame or t.id < 0:
            continue
        out[t.id] = next((name for name, b in tables
                          if len(b) and bool((np.abs(b - t.box[None]).max(axis=1) < 1e-6).any())), "other")
    return out


def run(clip: AnnotatedClip, config: PipelineConfig) -> tuple[list[tuple[int, Detections]], float, tuple[int, int],
                                                              dict[int, dict[int, str]]]:
    """The pipeline over ``clip``: ``([(frame, boxes)], horizon, (rows, cols), weak)``; the horizon
    is the one the bands were placed at after the first seconds (a fraction of the height);
    ``sources[frame]``: where each id returned on that frame got its box (:func:`_sources`)."""
    reader = FrameReader(str(clip.video), notify=lambda _n: None)
    frames = []
    weak: dict[int, dict[int, str]] = {}
    try:
        vd = video_detector_for(reader, make_detector(config), config)
        vd.warmup()
        for fno, frame, _ in reader:
            frames.append((fno, vd.update(frame)))
            weak[fno] = _sources(vd)
        h = getattr(vd.detector, "horizon", None)
        shape = reader.shape
    finally:
        reader.close()
    return frames, float(REFERENCE_HORIZON if h is None else h), (int(shape[0]), int(shape[1])), weak


def records(clip: AnnotatedClip, frames: list[tuple[int, Detections]], horizon: float, shape: tuple[int, int],
            weak: dict[int, dict[int, str]]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """``(boxes, targets)``: one record per returned box on a scored frame (module docstring)
    and one per target there (its width, dy and ratio)."""
    rows, cols = shape
    gt = clip.gt()
    by_frame = dict(gt.by_frame())
    kf = clip.keyframes()
    scored = set(int(f) for f in (kf if kf is not None else np.unique(gt.frames)))
    life: Counter[int] = Counter()
    for _, d in frames:
        if d.ids is not None:
            life.update(int(i) for i in d.ids)
    seen: Counter[int] = Counter()
    hrow = horizon * rows
    f = REF_ROWS / rows
    out, tout = [], []

    def geometry(b: np.ndarray) -> dict[str, Any]:
        w, h = float(b[2] - b[0]), float(b[3] - b[1])
        dy = float(b[3]) - hrow
        return dict(box=[float(v) for v in b], width=w * f, height=h * f, dy=dy / rows,
                    ratio=w / dy if dy > 0 else None, aspect=w / max(h, 1.0),
                    edge=bool(b[0] <= 1 or b[2] >= cols - 2), bottom_edge=bool(b[3] >= rows - 2),
                    centre=float(abs((b[0] + b[2]) / 2 - cols / 2) / cols))

    for fno, d in frames:
        ids = d.ids if d.ids is not None else np.full(len(d), -1)
        for i in ids:
            seen[int(i)] += 1
        if fno not in scored:
            continue
        g = by_frame.get(fno)
        targets = g.boxes[g.targets].astype(float) if g is not None else np.zeros((0, 4))
        ignores = g.boxes[~g.targets].astype(float) if g is not None else np.zeros((0, 4))
        for t in targets:
            tout.append(dict(frame=fno, **geometry(t)))
        if not len(d):
            continue
        boxes = d.boxes.astype(float)
        scores = d.scores if d.scores is not None else np.zeros(len(d))
        tp, dropped, _ = match_frame(boxes, scores, targets, ignores, 0.5)
        touch = (intersection(boxes, targets) > 0).any(1) if len(targets) else np.zeros(len(boxes), bool)
        touch_ign = (intersection(boxes, ignores) > 0).any(1) if len(ignores) else np.zeros(len(boxes), bool)
        for j, b in enumerate(boxes):
            kind = "hit" if tp[j] else "ignored" if dropped[j] else "near" if touch[j] else "clear"
            out.append(dict(frame=fno, kind=kind, score=float(scores[j]), id=int(ids[j]),
                            source=weak.get(fno, {}).get(int(ids[j]), '-'),
                            age=seen[int(ids[j])], life=life[int(ids[j])], touches_ignore=bool(touch_ign[j]),
                            **geometry(b)))
    return out, tout


def _fmt(v: float | None, p: str = ".2f") -> str:
    return "-" if v is None else format(v, p)


def box_lines(name: str, recs: list[dict[str, Any]]) -> list[str]:
    lines = []
    for r in recs:
        if r["kind"] not in ("near", "clear"):
            continue
        lines.append(f"| {name} | {r['frame']} | {r['kind']} | {r['width']:.0f} | {r['dy']:+.3f} | "
                     f"{_fmt(r['ratio'])} | {r['aspect']:.2f} | {r['score']:.1f} | {r['age']} | {r['life']} | "
                     f"{'yes' if r['edge'] else ''} | {r['centre']:.2f} | {'yes' if r['touches_ignore'] else ''} | "
                     f"{r['source']} |")
    return lines


def ratio_line(name: str, horizon: float, recs: list[dict[str, Any]], targets: list[dict[str, Any]]) -> str:
    def q(v: list[float]) -> str:
        if not v:
            return "-"
        a = np.asarray(v)
        return f"{a.min():.2f} / {np.median(a):.2f} / {a.max():.2f} ({len(a)})"

    inner = [t for t in targets if not t["edge"] and not t["bottom_edge"]]
    hit_recs = [r for r in recs if r["kind"] == "hit"]
    above = sum(1 for t in targets if t["ratio"] is None)
    return (f"| {name} | {horizon:.3f} | {q([t['ratio'] for t in inner if t['ratio'] is not None])} | {above} | "
            f"{q([t['ratio'] for t in hit_recs if t['ratio'] is not None])} | "
            f"{q([r['ratio'] for r in recs if r['kind'] in ('near', 'clear') and r['ratio'] is not None])} |")


def draw_crops(clip: AnnotatedClip, recs: list[dict[str, Any]], horizon: float, path: str) -> None:
    """One picture of every false alarm's surroundings (module docstring)."""
    fas = [r for r in recs if r["kind"] in ("near", "clear")]
    if not fas:
        return
    frames = read_frames_at(clip.video, sorted({r["frame"] for r in fas}))
    gt = dict(clip.gt().by_frame())
    tiles = []
    for r in fas:
        fr = frames[r["frame"]].copy()
        rows, cols = fr.shape[:2]
        y = int(round(horizon * rows))
        cv2.line(fr, (0, y), (cols - 1, y), (255, 0, 0), 1)
        g = gt.get(r["frame"])
        if g is not None:
            for b, t in zip(g.boxes, g.targets):
                colour = (0, 255, 0) if t else (128, 128, 128)
                cv2.rectangle(fr, (int(b[0]), int(b[1])), (int(b[2]), int(b[3])), colour, 1)
        x1, y1, x2, y2 = (int(v) for v in r["box"])
        cv2.rectangle(fr, (x1, y1), (x2, y2), (0, 0, 255), 2)
        w, h = x2 - x1, y2 - y1
        m = max(w, h)
        cx, cy = (x1 + x2) // 2, (y1 + y2) // 2
        a0, a1 = max(0, cx - m), min(cols, cx + m)
        b0, b1 = max(0, min(cy, y) - m), min(rows, max(cy, y) + m)
        crop = cv2.resize(fr[b0:b1, a0:a1], (240, 240))
        cv2.putText(crop, f"{r['frame']} {r['kind']} s{r['score']:.0f}", (4, 16), 0, 0.45, (255, 255, 255), 1)
        tiles.append(crop)
    per = 6
    while len(tiles) % per:
        tiles.append(np.zeros_like(tiles[0]))
    grid = np.vstack([np.hstack(tiles[i:i + per]) for i in range(0, len(tiles), per)])
    if not cv2.imwrite(path, grid):
        raise SystemExit(f"could not write {path}")


Rule = Callable[[Detections, float, tuple[int, int], dict[int, str], dict[int, int]], np.ndarray]


def _by_source(drop: str) -> Rule:
    def rule(d: Detections, h: float, shape: tuple[int, int], src: dict[int, str], age: dict[int, int]) -> np.ndarray:
        return np.array([src.get(int(i)) != drop for i in _ids(d)], bool)
    return rule


def _min_age(n: int, off_centre: float) -> Rule:
    def rule(d: Detections, h: float, shape: tuple[int, int], src: dict[int, str], age: dict[int, int]) -> np.ndarray:
        c = np.abs((d.boxes[:, 0] + d.boxes[:, 2]) / 2 - shape[1] / 2) / shape[1]
        return np.array([age[int(i)] >= n for i in _ids(d)], bool) | (c <= off_centre)
    return rule


def _inside(fraction: float) -> Rule:
    def rule(d: Detections, h: float, shape: tuple[int, int], src: dict[int, str], age: dict[int, int]) -> np.ndarray:
        b, sc = d.boxes.astype(float), _scores(d)
        inside = overlap_fraction(b, b)  # [i, j]: the fraction of box i inside box j
        np.fill_diagonal(inside, 0.0)
        return ~((inside >= fraction) & (sc[None, :] > sc[:, None])).any(axis=1)
    return rule


def _ids(d: Detections) -> np.ndarray:
    return d.ids if d.ids is not None else np.full(len(d), -1)


def _scores(d: Detections) -> np.ndarray:
    return d.scores.astype(float) if d.scores is not None else np.zeros(len(d))


def perspective_ok(boxes: np.ndarray, frame_shape: tuple[int, int], horizon: float, min_ratio: float,
                   max_ratio: float, slack: float) -> np.ndarray:
    """``(N,) bool``, True for each box of ``boxes (N, 4)`` (x1, y1, x2, y2 pixels of a frame of
    ``frame_shape = (rows, cols)``) whose width fits where it stands (a rule tried here; the
    pipeline's ``--perspective-filter`` that ran it was deleted, docs/accuracy.md). On a flat road
    a vehicle's width in pixels is ``W / h_c`` times the rows its bottom edge stands below the
    horizon (Hoiem, Efros & Hebert, CVPR 2006). With ``w`` the box's width and ``d`` the rows from
    the horizon (``horizon`` x rows) down to its bottom edge, both over the frame's rows, a box
    fails when ``d + slack <= w / max_ratio`` (too wide, or its bottom above the horizon by
    ``slack`` or more) or, unless it touches the frame's left or right edge, when ``d - slack >
    w / min_ratio`` (too narrow)."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    rows, cols = int(frame_shape[0]), int(frame_shape[1])
    w = (b[:, 2] - b[:, 0]) / rows
    d = b[:, 3] / rows - float(horizon)
    too_wide = d + slack <= w / max_ratio
    at_side = (b[:, 0] <= 1) | (b[:, 2] >= cols - 1)
    too_narrow = (d - slack > w / min_ratio) & ~at_side
    return ~(too_wide | too_narrow)


#: the rules ``--rules`` tries on the boxes a run returned (each keeps a box when True)
RULES: dict[str, Rule] = {
    "duplicates IoU > 0.5 (the stage's default)": lambda d, h, shape, src, age: duplicates(d.boxes, _scores(d), 0.5),
    "duplicates IoU > 0.4": lambda d, h, shape, src, age: duplicates(d.boxes, _scores(d), 0.4),
    "a box half inside a higher-scored one": _inside(0.5),
    "perspective [0.45, 12], slack 0.05 (the deleted --perspective-filter)":
        lambda d, h, shape, src, age: perspective_ok(d.boxes, shape, h, 0.45, 12.0, 0.05),
    "perspective [1.0, 12], slack 0": lambda d, h, shape, src, age: perspective_ok(d.boxes, shape, h, 1.0, 12.0, 0.0),
    "perspective [0.01, 3], slack 0": lambda d, h, shape, src, age: perspective_ok(d.boxes, shape, h, 0.01, 3.0, 0.0),
    "no box a weak blob kept": _by_source("weak"),
    "no box of the oncoming model": _by_source("oncoming"),
    "track returned >= 2 frames": _min_age(2, -1.0),
    "track returned >= 3 frames, off centre > 0.2": _min_age(3, 0.2),
}


def apply_rule(frames: list[tuple[int, Detections]], horizon: float, shape: tuple[int, int],
               sources: dict[int, dict[int, str]], rule: Rule) -> list[tuple[int, Detections]]:
    """``frames`` with the boxes ``rule`` rejects left out (what a last stage with the rule
    would return: the stages before it never see its decisions)."""
    age: Counter[int] = Counter()
    out = []
    for fno, d in frames:
        for i in _ids(d):
            age[int(i)] += 1
        out.append((fno, d[rule(d, horizon, shape, sources.get(fno, {}), age)] if len(d) else d))
    return out


def hits(clip: AnnotatedClip, frames: list[tuple[int, Detections]]) -> set[tuple[int, int]]:
    """``(frame, target id)`` of every target matched at IoU 0.5 on the scored frames."""
    gt = clip.gt()
    by_frame = dict(gt.by_frame())
    kf = clip.keyframes()
    scored = set(int(f) for f in (kf if kf is not None else np.unique(gt.frames)))
    out = set()
    for fno, d in frames:
        g = by_frame.get(fno)
        if fno not in scored or g is None or not len(d):
            continue
        tp, _, gi = match_frame(d.boxes, _scores(d), g.boxes[g.targets], g.boxes[~g.targets], 0.5)
        ids = g.ids[g.targets] if g.ids is not None else np.arange(int(g.targets.sum()))
        out |= {(fno, int(ids[j])) for j in gi[tp]}
    return out


def rule_lines(runs: dict[str, tuple[AnnotatedClip, list, float, tuple[int, int], dict]]) -> list[str]:
    """One row per rule of :data:`RULES`: per clip the false alarms, hits and hits lost."""
    lines = []
    for name, rule in {"none": None, **RULES}.items():
        cells = []
        for clip, frames, horizon, shape, sources in runs.values():
            new = frames if rule is None else apply_rule(frames, horizon, shape, sources, rule)
            sc = score_clip(clip.name, clip.gt(), Detections.from_frames(new), shape[0], clip.keyframes()).result
            lost = len(hits(clip, frames) - hits(clip, new))
            cells.append(f"{sc.fp} ({sc.fp_per_frame:.2f}) / {sc.tp} / {lost}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clips", default=None, help="comma-separated clip names (default: every annotated clip)")
    ap.add_argument("--no-plausible", action="store_true",
                    help="no plausibility stage (every box the tracker and the refinement give)")
    ap.add_argument("--loo-dir", default=None,
                    help="score each clip CLIP with the box regressor DIR/refine_without_CLIP.npz (made by "
                         "tools.studies.refine_loo --out-dir DIR): the honest leave-one-clip-out figures")
    ap.add_argument("--json", default=None, help="write every record to this JSON file")
    ap.add_argument("--crops", default=None, help="a folder for one picture of the false alarms per clip")
    ap.add_argument("--rules", action="store_true",
                    help="also: each rule of RULES applied to the boxes returned (per clip: false alarms (per "
                         "frame) / hits / hits lost); run it with --no-plausible")
    a = ap.parse_args()
    config = PipelineConfig()
    if a.no_plausible:
        config = replace(config, plausible=None)
    clips = [c for c in annotated_clips() if a.clips is None or c.name in a.clips.split(",")]
    scores, lines, ratio_lines, dump = [], [], [], {}
    runs: dict[str, tuple[AnnotatedClip, list, float, tuple[int, int], dict]] = {}
    kinds: dict[str, Counter[str]] = defaultdict(Counter)
    for clip in clips:
        cfg = config
        if a.loo_dir:
            path = Path(a.loo_dir) / f"refine_without_{clip.name}.npz"
            if not path.is_file():
                raise SystemExit(f"--loo-dir: no {path} (run tools.studies.refine_loo --out-dir {a.loo_dir} first)")
            cfg = replace(config, refine_model=str(path))
        frames, horizon, shape, weak = run(clip, cfg)
        runs[clip.name] = (clip, frames, horizon, shape, weak)
        preds = Detections.from_frames(frames, source=str(clip.video))
        scores.append(score_clip(clip.name, clip.gt(), preds, shape[0], clip.keyframes()))
        recs, targets = records(clip, frames, horizon, shape, weak)
        kinds[clip.name].update(r["kind"] for r in recs)
        lines += box_lines(clip.name, recs)
        ratio_lines.append(ratio_line(clip.name, horizon, recs, targets))
        dump[clip.name] = dict(horizon=horizon, shape=shape, boxes=recs, targets=targets)
        if a.crops:
            draw_crops(clip, recs, horizon, f"{a.crops}/{clip.name}_fa.png")
        print(f"{clip.name}: done", file=sys.stderr, flush=True)
    print(markdown_table(scores))
    print()
    print(table("| clip | hits | ignored | near | clear |",
                (f"| {c.name} | {k['hit']} | {k['ignored']} | {k['near']} | {k['clear']} |"
                 for c in clips for k in [kinds[c.name]])))
    print()
    print(table("| clip | horizon | target ratio min / median / max (n; off the frame's edges) | targets with bottom "
                "above it | hits' ratio | false alarms' ratio |", ratio_lines))
    print()
    print(table("| clip | frame | kind | width (ref px) | dy (bottom - horizon, / height) | ratio | aspect | score | "
                "age | life | side edge | off centre | touches ignore | box from |", lines))
    if a.rules:
        print()
        print(table("| rule (false alarms (per frame) / hits / hits lost) | " + " | ".join(runs) + " |",
                    rule_lines(runs)))
    if a.json:
        write_bytes(a.json, json.dumps(dump, indent=1).encode())


if __name__ == "__main__":
    main()

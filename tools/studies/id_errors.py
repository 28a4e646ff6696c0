"""Why identities score below boxes: a tracked run's identity errors counted by cause, per clip.

Each annotated clip (``$FASTDET_DATA``; keyframe clips on their keyframes only) is run
through the default video pipeline (or read from ``--pred-dir DIR/CLIP.txt``), its boxes
matched to the targets frame by frame as ``fastdet eval`` matches them (IoU 0.5, greedy by
score, boxes on ignore regions dropped: :func:`fastdet.eval.matching.match_frame`), and each
target's *timeline* -- the id of the box that hit it on each of its scored frames, or a
miss -- is read for the causes below. Box F1, MOTA, IDF1, HOTA, id switches and
fragmentations are :func:`fastdet.eval.evaluate`'s.

Per target, over its scored frames:

- ``late``: frames missed before its first hit (a track that starts late);
- ``gap``: frames missed between two hits, and ``gaps``: the number of such runs;
- ``end``: frames missed after its last hit (a track that ends early);
- ``never``: frames of targets never hit;
- an id change between two consecutive hits is ``new after gap`` (the target was missed in
  between and came back under an id never seen before: its track died over the gap, or was
  not found again), ``taken after gap`` (came back under an id that had hit another target:
  a track that jumped to this vehicle), ``switch`` (no miss in between: neighbours that
  swapped ids, or a duplicate box that took over);
- ``off-id hits``: hits under another id than the one IDF1's optimal one-to-one pairing of
  target ids and track ids gives the target (the hits the identity loses; each is a true
  positive that is not an identity true positive).

Per run: ``ids on 2+`` (track ids that hit two or more targets), ``dup FP`` (false positives
with IoU >= 0.3 with a target that another box hit on that frame: a duplicate box or the
part of a split) and ``FP`` (every false positive).

Tracker settings: ``--set KEY=VALUE[,KEY=VALUE...]`` (repeatable; each one a row, after the
defaults' row) runs the pipeline with those :class:`~fastdet.config.TrackerConfig` fields;
``--offline`` adds the offline pass (gap interpolation) to every row. The pipeline's guided
search reads the tracks, so a tracker setting may move the boxes too: each row is a full
run of the pipeline, never a replay of the tracker alone::

    python -m tools.studies.id_errors [--clips test_small1,test_video] [--set hold_row=false]
        [--offline] [--variants original,mirror,...] [--events] [--json OUT.json]

``--appearance`` measures instead whether a colour histogram of a vehicle's box could tell
neighbours apart (the appearance cue of re-identifying trackers, e.g. norfair's): per clip, the
Bhattacharyya distance between the histograms of the *annotated* boxes of the same vehicle
1 and up to 3 scored frames apart, against that between two vehicles side by side (box centres
within two widths) within 3 frames -- for a hue-saturation (8 x 4), an RGB (4 x 4 x 4) and an
rg-chromaticity (8 x 8) histogram. A veto on the distance can split neighbours only if their
smallest distance is above the same vehicle's largest.

``--variants`` runs each clip's camera-shift copies instead (:func:`fastdet.eval.variants.
standard_variants`: other resolutions, wider lenses, the horizon moved, the right side cut,
mirrored, re-encoded; the ground truth moved with the pixels), each through a fresh
``VideoDetector`` primed with its first frames as a file run is (``tools.studies.camera_shift``).
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from fastdet.config import PipelineConfig, TrackerConfig
from fastdet.detections import Detections
from fastdet.eval import evaluate
from fastdet.eval.clips import AnnotatedClip, annotated_clips
from fastdet.eval.matching import match_frame
from fastdet.io.atomic import write_bytes
from fastdet.io.motfiles import read_predictions

#: the Udacity clips, annotated on every frame with ids
DEFAULT_CLIPS = ("test_small1", "test_video")
#: IoU of a box with a vehicle that another box hit, for the box to count as a duplicate
DUP_IOU = 0.3


@dataclass
class Causes:
    """Counts of one run on one clip (module docstring); ``events``: one line per id change."""

    late: int = 0
    gap: int = 0
    gaps: int = 0
    end: int = 0
    never: int = 0
    new_after_gap: int = 0
    taken_after_gap: int = 0
    switch: int = 0
    off_id_hits: int = 0
    ids_on_two: int = 0
    dup_fp: int = 0
    fp: int = 0
    events: list[str] = field(default_factory=list)

    def counts(self) -> dict[str, int]:
        return {k: v for k, v in self.__dict__.items() if k != "events"}


def _frames(gt: Detections, keyframes: np.ndarray | None) -> np.ndarray:
    if keyframes is not None:
        return np.unique(np.asarray(keyframes, np.int64))
    assert gt.frames is not None
    return np.arange(1, int(gt.frames.max()) + 1 if len(gt) else 1, dtype=np.int64)


def timelines(gt: Detections, preds: Detections, keyframes: np.ndarray | None = None,
              iou: float = 0.5) -> tuple[dict[int, list[tuple[int, int | None]]], Counter, int]:
    """``(timeline, ...)``: per target id, ``[(frame, track id or None), ...]`` over its scored
    frames in order; the Counter of ``dup`` / ``fp`` boxes; and the number of scored frames.

    gt: the clip's ground truth; preds: boxes with ``ids`` (a box without an id, -1, is a
    track of its own). Matching: :func:`match_frame`, as ``fastdet eval``."""
    frames = _frames(gt, keyframes)
    assert gt.frames is not None and gt.ids is not None and preds.frames is not None and preds.scores is not None
    ids: np.ndarray = preds.ids if preds.ids is not None else np.full(len(preds), -1, np.int64)
    line: dict[int, list[tuple[int, int | None]]] = defaultdict(list)
    fps: Counter = Counter()
    for f in frames:
        g, p = gt.frames == f, preds.frames == f
        targets = g & gt.targets
        tb, tid = gt.boxes[targets], gt.ids[targets]
        pb, ps, pid = preds.boxes[p], preds.scores[p], ids[p]
        tp, dropped, gi = match_frame(pb, ps, tb, gt.boxes[g & ~gt.targets], iou)
        hit = {int(j): int(pid[k]) for k, j in enumerate(gi) if tp[k]}
        for j, t in enumerate(tid):
            line[int(t)].append((int(f), hit.get(j)))
        fp = ~tp & ~dropped
        if fp.any():
            fps["fp"] += int(fp.sum())
            if tp.any() and len(tb):
                from fastdet.boxes import iou as box_iou  # noqa: PLC0415 - only on frames with both

                near = box_iou(pb[fp].astype(np.float64), tb[gi[tp]].astype(np.float64)).max(axis=1)
                fps["dup"] += int((near >= DUP_IOU).sum())
    return dict(line), fps, len(frames)


def _id_pairing(line: dict[int, list[tuple[int, int | None]]]) -> dict[int, int]:
    """IDF1's one-to-one pairing of target ids and track ids that keeps the most hits."""
    from scipy.optimize import linear_sum_assignment  # noqa: PLC0415

    targets = sorted(line)
    tracks = sorted({i for t in targets for _, i in line[t] if i is not None})
    if not targets or not tracks:
        return {}
    co = np.zeros((len(targets), len(tracks)))
    col = {i: k for k, i in enumerate(tracks)}
    for r, t in enumerate(targets):
        for _, i in line[t]:
            if i is not None:
                co[r, col[i]] += 1
    rows, cols = linear_sum_assignment(co, maximize=True)
    return {targets[r]: tracks[c] for r, c in zip(rows, cols) if co[r, c] > 0}


def causes(gt: Detections, preds: Detections, keyframes: np.ndarray | None = None, iou: float = 0.5) -> Causes:
    """The identity errors of ``preds`` on a clip, by cause (module docstring)."""
    line, fps, _ = timelines(gt, preds, keyframes, iou)
    c = Causes(dup_fp=fps["dup"], fp=fps["fp"])
    owner = _id_pairing(line)
    hits_of: dict[int, list[tuple[int, int]]] = defaultdict(list)  # track id -> [(frame, target)]
    for t, seq in line.items():
        for f, i in seq:
            if i is not None:
                hits_of[i].append((f, t))
    c.ids_on_two = sum(len({t for _, t in v}) >= 2 for v in hits_of.values())
    for t, seq in sorted(line.items()):
        hit = [k for k, (_, i) in enumerate(seq) if i is not None]
        if not hit:
            c.never += len(seq)
            continue
        c.late += hit[0]
        c.end += len(seq) - 1 - hit[-1]
        c.off_id_hits += sum(1 for k in hit if seq[k][1] != owner.get(t))
        for a, b in zip(hit, hit[1:]):
            missed = b - a - 1
            if missed:
                c.gap += missed
                c.gaps += 1
            (fa, ia), (fb, ib) = seq[a], seq[b]
            if ia == ib:
                continue
            assert ib is not None
            if not missed:
                kind = "switch"
                c.switch += 1
            elif any(fo < fb and to != t for fo, to in hits_of[ib]):
                kind = "taken after gap"
                c.taken_after_gap += 1
            else:
                kind = "new after gap"
                c.new_after_gap += 1
            c.events.append(f"target {t}: id {ia} (frame {fa}) -> id {ib} (frame {fb}), {missed} scored "
                            f"frame(s) missed between: {kind}")
    return c


#: the histograms of ``--appearance``: name -> bins
HISTOGRAMS = {"hue-sat 8x4": (8, 4), "rgb 4x4x4": (4, 4, 4), "rg-chroma 8x8": (8, 8)}


def colour_histogram(crop: np.ndarray, kind: str) -> np.ndarray:
    """The normalised histogram (flat, float64, sums to 1) of a BGR ``crop (h, w, 3) uint8``:
    ``kind`` one of :data:`HISTOGRAMS` (hue-saturation in OpenCV's HSV; RGB; the
    chromaticities (r + 1) / (r + g + b + 3) and (g + 1) / (r + g + b + 3) in 8 bins each over
    [0.2, 0.5], values beyond it in the end bins: grey is 1/3)."""
    import cv2  # noqa: PLC0415

    px = crop.reshape(-1, 3)
    if kind.startswith("hue-sat"):
        hsv = cv2.cvtColor(np.ascontiguousarray(crop), cv2.COLOR_BGR2HSV).reshape(-1, 3).astype(np.int64)
        idx = np.minimum(hsv[:, 0] * 8 // 180, 7) * 4 + hsv[:, 1] * 4 // 256
        h = np.bincount(idx, minlength=32)
    elif kind.startswith("rgb"):
        q = px.astype(np.int64) // 64
        h = np.bincount(q[:, 2] * 16 + q[:, 1] * 4 + q[:, 0], minlength=64)
    else:
        f = px.astype(np.float64) + 1
        tot = f.sum(1)
        r, g = (np.clip(c / tot, 0.2, 0.5) for c in (f[:, 2], f[:, 1]))
        br, bg = (np.minimum(((c - 0.2) / 0.3 * 8).astype(np.int64), 7) for c in (r, g))
        idx = br * 8 + bg
        h = np.bincount(idx, minlength=64)
    h = np.asarray(h, np.float64)
    return h / max(h.sum(), 1e-12)


def bhattacharyya(a: np.ndarray, b: np.ndarray) -> float:
    """Bhattacharyya distance sqrt(1 - sum sqrt(a b)) of two normalised histograms (0: the same)."""
    return float(np.sqrt(max(0.0, 1.0 - float(np.sum(np.sqrt(a * b))))))


def appearance(clip: AnnotatedClip, window: int = 3) -> dict[str, dict[str, float]]:
    """``--appearance`` on one clip (module docstring): per histogram, ``same_1`` (largest
    distance of a vehicle to itself on the next scored frame), ``same`` (largest within
    ``window`` scored frames), ``neighbours`` (smallest between two vehicles side by side
    within ``window`` scored frames; ``nan`` when no two are), and the counts of pairs."""
    from fastdet.io.reader import read_frames_at  # noqa: PLC0415

    gt, kf = clip.gt(), clip.keyframes()
    assert gt.frames is not None and gt.ids is not None
    frames = _frames(gt, kf)
    images = read_frames_at(clip.video, frames.tolist())
    boxes: dict[int, list[tuple[int, int, np.ndarray]]] = defaultdict(list)  # frame rank -> [(id, x, box)]
    for rank, f in enumerate(frames):
        if int(f) not in images:
            continue
        g = (gt.frames == f) & gt.targets
        for i, b in zip(gt.ids[g], gt.boxes[g]):
            boxes[rank].append((int(i), int(f), np.asarray(b, np.float64)))
    out: dict[str, dict[str, float]] = {}
    for kind in HISTOGRAMS:
        hist: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        for rank, items in boxes.items():
            for i, f, b in items:
                h_, w_ = images[f].shape[:2]
                x1, y1, x2, y2 = (int(round(v)) for v in (max(b[0], 0), max(b[1], 0), min(b[2], w_), min(b[3], h_)))
                if x2 - x1 >= 2 and y2 - y1 >= 2:
                    hist[(rank, i)] = (colour_histogram(images[f][y1:y2, x1:x2], kind), b)
        same1, same, near = [], [], []
        for (r, i), (ha, ba) in hist.items():
            for d in range(0, window + 1):
                for (r2, j), (hb, bb) in ((k, v) for k, v in hist.items() if k[0] == r + d):
                    if i == j and d >= 1:
                        same.append(bhattacharyya(ha, hb))
                        if d == 1:
                            same1.append(bhattacharyya(ha, hb))
                    elif i != j and (d >= 1 or i < j):
                        w = max(ba[2] - ba[0], bb[2] - bb[0])
                        if abs((ba[0] + ba[2]) - (bb[0] + bb[2])) / 2 <= 2 * w and \
                                abs((ba[1] + ba[3]) - (bb[1] + bb[3])) / 2 <= w:
                            near.append(bhattacharyya(ha, hb))
        out[kind] = {"same_1": max(same1, default=float("nan")), "same": max(same, default=float("nan")),
                     "neighbours": min(near, default=float("nan")), "same_pairs": len(same),
                     "neighbour_pairs": len(near)}
    return out


def parse_set(text: str) -> dict[str, Any]:
    """``'hold_row=false,max_lost=10'`` -> ``{'hold_row': False, 'max_lost': 10}`` (values as
    JSON, else strings); ``ValueError`` for a key that is not a TrackerConfig field."""
    out: dict[str, Any] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        if "=" not in part:
            raise ValueError(f"--set: {part!r} is not KEY=VALUE")
        k, v = (s.strip() for s in part.split("=", 1))
        try:
            out[k] = json.loads(v.lower() if v.lower() in ("true", "false") else v)
        except json.JSONDecodeError:
            out[k] = v
    TrackerConfig.from_dict({**TrackerConfig().to_dict(), **out})  # unknown keys, bad values
    return out


def run_clip(clip: AnnotatedClip, tracker: TrackerConfig, offline: bool) -> Detections:
    from fastdet.video import iter_video_detections  # noqa: PLC0415 - numba start-up only when run

    config = replace(PipelineConfig(), tracker=tracker)
    return Detections.from_frames(iter_video_detections(str(clip.video), config, progress=False, offline=offline),
                                  source=str(clip.video))


def run_frames(frames: list[np.ndarray], tracker: TrackerConfig, offline: bool) -> Detections:
    """The default pipeline with ``tracker`` on frames held in memory (a camera-shift copy),
    its horizon primed from the first frames as a file run's is."""
    from fastdet.video import VideoDetector, make_detector  # noqa: PLC0415
    from fastdet.video.run import defer_plausible, offline_boxes  # noqa: PLC0415

    config = replace(PipelineConfig(), tracker=tracker)
    vd = VideoDetector(make_detector(config), config)
    if offline:
        defer_plausible(vd)
    vd.prime_horizon(frames)
    out = [(i, vd.update(f)) for i, f in enumerate(frames, start=1)]
    if offline:
        out = offline_boxes(vd, out, frames[0].shape)
    return Detections.from_frames(out)


def _row(name: str, setting: str, r: Any, c: Causes) -> str:
    k = c.counts()
    return (f"| {name} | {setting} | {r.f1:.3f} | {r.mota:.3f} | {r.idf1:.3f} | {r.hota:.3f} | {r.id_switches} | "
            f"{r.fragmentations} | {k['off_id_hits']} | "
            f"{k['new_after_gap']} / {k['taken_after_gap']} / {k['switch']} | "
            f"{k['late']} / {k['gap']} ({k['gaps']}) / {k['end']} / {k['never']} | {k['ids_on_two']} | "
            f"{k['dup_fp']} / {k['fp']} |")


HEADER = ("| clip | tracker | F1 | MOTA | IDF1 | HOTA | switches | frag. | off-id hits | new after gap / taken "
          "after gap / switch | missed: late / gap (gaps) / end / never | ids on 2+ | dup FP / FP |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", default=",".join(DEFAULT_CLIPS), help="comma-separated clip names, or 'all'")
    ap.add_argument("--data", default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    ap.add_argument("--pred-dir", default=None, help="read DIR/CLIP.txt instead of running the pipeline "
                    "(the defaults' row only)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE,...",
                    help="a row with these TrackerConfig fields (repeatable)")
    ap.add_argument("--offline", action="store_true", help="every row with the offline pass (video --offline)")
    ap.add_argument("--variants", default=None, help="camera-shift copies of each clip to run, comma-separated "
                    "(names of fastdet.eval.variants.standard_variants, e.g. original,mirror,960x540), or 'all'")
    ap.add_argument("--events", action="store_true", help="list every id change")
    ap.add_argument("--appearance", action="store_true", help="instead: colour-histogram distances of the "
                    "annotated boxes, the same vehicle against neighbours (no pipeline run)")
    ap.add_argument("--json", default=None, help="write the counts to this JSON file")
    a = ap.parse_args(argv)
    sets: list[tuple[str, dict[str, Any]]] = [("defaults", {})]
    try:
        sets += [(s, parse_set(s)) for s in a.set]
    except ValueError as err:
        print(f"id_errors: {err}", file=sys.stderr)
        return 2
    if a.pred_dir is not None and len(sets) > 1:
        print("id_errors: --set runs the pipeline; not with --pred-dir", file=sys.stderr)
        return 2
    clips = annotated_clips(a.data)
    if a.clips != "all":
        want = [c for c in a.clips.split(",") if c]
        missing = sorted(set(want) - {c.name for c in clips})
        if missing:
            print(f"id_errors: no annotated clip named {', '.join(missing)}", file=sys.stderr)
            return 2
        clips = [c for c in clips if c.name in want]
    variants: list[Any] = [None]
    if a.variants is not None:
        from fastdet.eval.variants import standard_variants  # noqa: PLC0415

        known = {v.name: v for v in standard_variants()}
        names = list(known) if a.variants == "all" else [v for v in a.variants.split(",") if v]
        unknown = [n for n in names if n not in known]
        if unknown or a.pred_dir is not None:
            print(f"id_errors: --variants: {', '.join(unknown) or 'not with --pred-dir'} (have: {', '.join(known)})",
                  file=sys.stderr)
            return 2
        variants = [known[n] for n in names]
    if a.appearance:
        print("| clip | histogram | same vehicle, next frame (largest) | same vehicle, <= 3 frames (largest) | "
              "neighbours, <= 3 frames (smallest) | pairs (same / neighbours) |\n|---|---|---|---|---|---|")
        rows = []
        for clip in clips:
            for kind, r in appearance(clip).items():
                print(f"| {clip.name} | {kind} | {r['same_1']:.3f} | {r['same']:.3f} | {r['neighbours']:.3f} | "
                      f"{r['same_pairs']} / {r['neighbour_pairs']} |", flush=True)
                rows.append({"clip": clip.name, "histogram": kind, **r})
        if a.json:
            write_bytes(a.json, json.dumps(rows, indent=1).encode())
        return 0
    print(HEADER)
    dump: list[dict[str, Any]] = []
    for label, kw in sets:
        tracker = replace(TrackerConfig(), **kw)
        for clip in clips:
            gt0, kf = clip.gt(), clip.keyframes()
            src = None
            for v in variants:
                name, gt = clip.name, gt0
                if a.pred_dir is not None:
                    preds = read_predictions(f"{a.pred_dir}/{clip.name}.txt")
                elif v is None:
                    preds = run_clip(clip, tracker, a.offline)
                else:
                    import tempfile  # noqa: PLC0415
                    from pathlib import Path  # noqa: PLC0415

                    from fastdet.eval.variants import transform_gt  # noqa: PLC0415
                    from fastdet.io.reader import read_frames  # noqa: PLC0415
                    from tools.studies.camera_shift import variant_frames  # noqa: PLC0415

                    src = src if src is not None else read_frames(clip.video)
                    with tempfile.TemporaryDirectory(prefix="fastdet_id_errors_") as tmp:
                        frames = variant_frames(src, v, clip.name, Path(tmp))
                    gt = transform_gt(gt0, v, src[0].shape[:2])
                    preds = run_frames(frames, tracker, a.offline)
                    name = f"{clip.name} {v.name}"
                r = evaluate(gt, preds, iou=0.5, keyframes=kf, tracking=True)
                c = causes(gt, preds, kf)
                print(_row(name, label + (" offline" if a.offline else ""), r, c), flush=True)
                if a.events:
                    for event in c.events:
                        print(f"|   | {event} |")
                dump.append({"clip": clip.name, "variant": None if v is None else v.name, "set": kw,
                             "offline": a.offline, **r.to_dict(), **c.counts(), "events": c.events})
    if a.json:
        write_bytes(a.json, json.dumps(dump, indent=1).encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())

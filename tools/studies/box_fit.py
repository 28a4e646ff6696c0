"""Every false alarm and every missed target, held out, against the box nearest to it (run by
hand; docs/accuracy.md "Boxes that fit the vehicle").

Each clip runs as :mod:`tools.studies.refine_loo` runs it (the pipeline without refinement,
cached in ``--loo-dir``; then refined by ``DIR/refine_without_CLIP.npz``, the regressor that
never saw the clip's camera, and filtered by the plausibility stage), and on every scored frame:

- each **false alarm** (a returned box matched to no target at IoU 0.5 and not on an ignore
  region) against the target it overlaps most: that IoU, how it lies (``inside``: at least 0.8
  of the box inside the target and less than 0.8 of the target inside the box; ``contains``: the
  other way round; ``offset``: neither; ``clear``: touches no target), the box's aspect (width /
  height) over the target's, its width and height over the target's, how many targets have half
  their area or more inside it (``two``: 2 or more), and the IoU of the same track's box before
  the refinement and of the best heat-map box;
- each **missed target** against the best returned box (IoU, how it lies, whether that box hit
  another target), the best box before the refinement and the best heat-map box (before the
  tracker), the main-model windows overlapping it at IoU >= 0.3 and its peak heat; a miss is
  ``no box`` (no returned box touches it at IoU >= 0.1), else ``box misses`` (one does, below 0.5).

    python -m tools.studies.box_fit --loo-dir DIR [--clips A,B] [--pictures OUTDIR] [--json OUT]
        [small_boxes settings, e.g. --refine iterations=3]

``--pictures OUTDIR`` writes ``OUTDIR/CLIP.png``: every scored frame with a false alarm or a miss
(at most 12), the targets (green), the ignore regions (grey), the returned boxes (red: a false
alarm, thick; a hit, thin), the boxes before the refinement (yellow) and the heat maps' boxes
(blue).
"""
from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fastdet.boxes import intersection, iou
from fastdet.detections import Detections
from fastdet.eval.clips import annotated_clips, markdown_table, score_clip
from fastdet.eval.matching import match_frame
from fastdet.io.atomic import write_bytes
from fastdet.video.refine import load_regressor
from tools.studies.markdown import table

from .refine_loo import ClipRun, refined, unrefined_run
from .small_boxes import add_setting_arguments, config_from

REF_ROWS = 720


def relation(box: np.ndarray, target: np.ndarray, inside: float = 0.8) -> str:
    """How ``box`` (4,) lies on ``target`` (4,) (module docstring): ``inside``, ``contains``,
    ``offset`` or ``clear``."""
    inter = float(intersection(box[None].astype(float), target[None].astype(float))[0, 0])
    if inter <= 0:
        return "clear"
    ab = max((box[2] - box[0]) * (box[3] - box[1]), 1e-9)
    at = max((target[2] - target[0]) * (target[3] - target[1]), 1e-9)
    fb, ft = inter / ab, inter / at
    if fb >= inside and ft < inside:
        return "inside"
    if ft >= inside and fb < inside:
        return "contains"
    return "offset"


def _aspect(b: np.ndarray) -> float:
    return float((b[2] - b[0]) / max(b[3] - b[1], 1e-9))


def _best(box_or_target: np.ndarray, others: np.ndarray) -> tuple[float, int]:
    if not len(others):
        return 0.0, -1
    m = iou(box_or_target[None].astype(float), np.asarray(others, float).reshape(-1, 4))[0]
    k = int(np.argmax(m))
    return float(m[k]), k


def count_clip(run: ClipRun, rec: dict) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """``(false alarms, misses)`` of one clip's refined records (module docstring)."""
    gt = run.clip.gt()
    assert gt.frames is not None and gt.consider is not None and gt.ids is not None  # ground truth has them
    f = REF_ROWS / run.rows
    fas, misses = [], []
    for fno, r in sorted(rec.items()):
        g = np.flatnonzero(gt.frames == fno)
        tb = gt.boxes[g[gt.consider[g]]].astype(float)
        ib = gt.boxes[g[~gt.consider[g]]].astype(float)
        tid = gt.ids[g[gt.consider[g]]]
        out: Detections = r["out"]
        raw: Detections = run.rec[fno]["out"]
        heat: Detections = r["boxes"]
        ob = out.boxes.astype(float)
        scores = out.scores if out.scores is not None else np.zeros(len(out))
        tp, dropped, gi = match_frame(ob, scores, tb, ib, 0.5)
        hit = np.zeros(len(tb), bool)
        hit[gi[tp]] = True
        raw_by_id = {int(i): b for i, b in zip(raw.ids if raw.ids is not None else [], raw.boxes)}
        for k in np.flatnonzero(~tp & ~dropped):
            b = ob[k]
            v, j = _best(b, tb)
            item: dict[str, Any] = dict(frame=fno, box=b.tolist(), width=float((b[2] - b[0]) * f), iou=v,
                                        relation="clear" if v <= 0 else relation(b, tb[j]), score=float(scores[k]))
            if len(tb):
                inside_t = intersection(b[None], tb)[0] / np.maximum((tb[:, 2] - tb[:, 0]) * (tb[:, 3] - tb[:, 1]), 1)
                item["covers"] = int((inside_t >= 0.5).sum())
            if v > 0:
                t = tb[j]
                item.update(target=int(tid[j]), target_width=float((t[2] - t[0]) * f),
                            aspect_ratio=_aspect(b) / _aspect(t), wr=float((b[2] - b[0]) / (t[2] - t[0])),
                            hr=float((b[3] - b[1]) / (t[3] - t[1])), target_hit=bool(hit[j]),
                            cx_off=float(((b[0] + b[2]) - (t[0] + t[2])) / 2 / (t[2] - t[0])),
                            cy_off=float(((b[1] + b[3]) - (t[1] + t[3])) / 2 / (t[3] - t[1])),
                            target_aspect=_aspect(t))
                if out.ids is not None and int(out.ids[k]) in raw_by_id:
                    item["raw_iou"] = float(iou(raw_by_id[int(out.ids[k])][None].astype(float), t[None])[0, 0])
                item["heat_iou"] = _best(t, heat.boxes)[0]
            fas.append(item)
        for jj in np.flatnonzero(~hit):
            j = int(jj)
            t = tb[j]
            v, kb = _best(t, ob)
            item = dict(frame=fno, target=int(tid[j]), box=t.tolist(), width=float((t[2] - t[0]) * f),
                        aspect=_aspect(t), iou=v, kind="no box" if v < 0.1 else "box misses")
            if v > 0:
                item.update(relation=relation(ob[kb], t), box_hits_other=bool(tp[kb]),
                            aspect_ratio=_aspect(ob[kb]) / _aspect(t),
                            wr=float((ob[kb][2] - ob[kb][0]) / (t[2] - t[0])),
                            hr=float((ob[kb][3] - ob[kb][1]) / (t[3] - t[1])))
            item["raw_iou"] = _best(t, raw.boxes)[0]
            item["heat_iou"] = _best(t, heat.boxes)[0]
            wins = run.rec[fno]["windows"]
            item["windows"] = int((iou(t[None], wins.boxes.astype(float))[0] >= 0.3).sum()) if len(wins) else 0
            hm = run.rec[fno]["heat"]
            cell = -(-run.rows // hm.shape[0])
            sub = hm[int(t[1]) // cell:int(np.ceil(t[3] / cell)), int(t[0]) // cell:int(np.ceil(t[2] / cell))]
            item["peak"] = float(sub.max()) if sub.size else 0.0
            misses.append(item)
    return fas, misses


def _f(v: Any, p: str = ".2f") -> str:
    return "-" if v is None else format(v, p)


def fa_rows(name: str, fas: list[dict[str, Any]]) -> list[str]:
    return [f"| {name} | {a['frame']} | {a['width']:.0f} | {a['relation']} | {a['iou']:.2f} | {a.get('covers', 0)} | "
            f"{_f(a.get('target_width'), '.0f')} | {_f(a.get('target_aspect'))} | {_f(a.get('aspect_ratio'))} | "
            f"{_f(a.get('wr'))} | {_f(a.get('hr'))} | {_f(a.get('cx_off'))} | {_f(a.get('cy_off'))} | "
            f"{'yes' if a.get('target_hit') else ''} | {_f(a.get('raw_iou'))} | {_f(a.get('heat_iou'))} |"
            for a in fas]


def miss_rows(name: str, misses: list[dict[str, Any]]) -> list[str]:
    return [f"| {name} | {m['frame']} | {m['target']} | {m['width']:.0f} | {m['aspect']:.2f} | {m['kind']} | "
            f"{m['iou']:.2f} | {m.get('relation', '-')} | {'yes' if m.get('box_hits_other') else ''} | "
            f"{_f(m.get('wr'))} | {_f(m.get('hr'))} | {m['raw_iou']:.2f} | {m['heat_iou']:.2f} | {m['windows']} | "
            f"{m['peak']:.1f} |" for m in misses]


def draw(run: ClipRun, rec: dict, fas: list[dict[str, Any]], misses: list[dict[str, Any]], path: str) -> None:
    """The picture of ``--pictures`` (module docstring)."""
    frames = sorted({a["frame"] for a in fas} | {m["frame"] for m in misses})[:12]
    if not frames:
        return
    gt = dict(run.clip.gt().by_frame())
    fa_boxes = {(a["frame"], tuple(a["box"])) for a in fas}
    tiles = []
    for fno in frames:
        fr = run.images[fno].copy()
        g = gt.get(fno)
        if g is not None:
            for b, t in zip(g.boxes, g.targets):
                colour = (0, 255, 0) if t else (128, 128, 128)
                cv2.rectangle(fr, (int(b[0]), int(b[1])), (int(b[2]), int(b[3])), colour, 1)
        for b in rec[fno]["boxes"].boxes:
            cv2.rectangle(fr, (int(b[0]), int(b[1])), (int(b[2]), int(b[3])), (255, 0, 0), 1)
        for b in run.rec[fno]["out"].boxes:
            cv2.rectangle(fr, (int(b[0]), int(b[1])), (int(b[2]), int(b[3])), (0, 255, 255), 1)
        for b in rec[fno]["out"].boxes:
            thick = 2 if (fno, tuple(float(v) for v in b)) in fa_boxes else 1
            cv2.rectangle(fr, (int(b[0]), int(b[1])), (int(b[2]), int(b[3])), (0, 0, 255), thick)
        cv2.putText(fr, str(fno), (5, 25), 0, 0.8, (255, 255, 255), 2)
        tiles.append(cv2.resize(fr, (960, int(960 * fr.shape[0] / fr.shape[1]))))
    if len(tiles) % 2:
        tiles.append(np.zeros_like(tiles[0]))
    grid = np.vstack([np.hstack(tiles[i:i + 2]) for i in range(0, len(tiles), 2)])
    ok, buf = cv2.imencode(".png", grid)
    if not ok:
        raise SystemExit(f"box_fit: could not encode {path}")
    write_bytes(path, buf.tobytes())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--loo-dir", required=True,
                    help="the folder of tools.studies.refine_loo --out-dir: refine_without_CLIP.npz and the run cache")
    ap.add_argument("--clips", default=None, help="comma-separated clip names (default: every annotated clip)")
    ap.add_argument("--pictures", default=None, help="a folder for one picture per clip")
    ap.add_argument("--json", default=None, help="write every record to this JSON file")
    add_setting_arguments(ap)
    a = ap.parse_args()
    loo = Path(a.loo_dir)
    config = config_from(a)
    clips = [c for c in annotated_clips() if a.clips is None or c.name in a.clips.split(",")]
    scores, fa_lines, miss_lines, totals, dump = [], [], [], [], {}
    for clip in clips:
        path = loo / f"refine_without_{clip.name}.npz"
        if not path.is_file():
            raise SystemExit(f"box_fit: no {path} (run tools.studies.refine_loo --out-dir {loo} first)")
        run = unrefined_run(clip, a, loo)
        frames, rec = refined(run, load_regressor(path), config)
        preds = Detections.from_frames(frames, source=str(clip.video))
        scores.append(score_clip(clip.name, clip.gt(), preds, run.rows, clip.keyframes()))
        fas, misses = count_clip(run, rec)
        fa_lines += fa_rows(clip.name, fas)
        miss_lines += miss_rows(clip.name, misses)
        rel = Counter(x["relation"] for x in fas)
        kinds = Counter(m["kind"] for m in misses)
        totals.append(f"| {clip.name} | {len(fas)} | {rel['inside']} | {rel['contains']} | {rel['offset']} | "
                      f"{rel['clear']} | {sum(1 for x in fas if x.get('covers', 0) >= 2)} | {len(misses)} | "
                      f"{kinds['box misses']} | {kinds['no box']} | {sum(1 for m in misses if m['heat_iou'] >= 0.5)} |")
        dump[clip.name] = dict(false_alarms=fas, misses=misses)
        if a.pictures:
            Path(a.pictures).mkdir(parents=True, exist_ok=True)
            draw(run, rec, fas, misses, f"{a.pictures}/{clip.name}.png")
    print(markdown_table(scores))
    print()
    print(table("| clip | false alarms | inside a target | contains one | offset | clear | over 2+ targets | misses | "
                "a box misses it | no box | a heat box fits it (IoU >= 0.5) |", totals))
    print()
    print(table("| clip | frame | width | relation | IoU | targets half inside | target width | target aspect | "
                "aspect / target's | w ratio | h ratio | centre x off (/w) | centre y off (/h) | "
                "target hit by another | IoU before refine | best heat box IoU |", fa_lines))
    print()
    print(table("| clip | frame | target | width | aspect | kind | best box IoU | relation | that box hits another | "
                "w ratio | h ratio | best IoU before refine | best heat box IoU | windows IoU >= 0.3 | peak heat |",
                miss_lines))
    if a.json:
        write_bytes(a.json, json.dumps(dump, indent=1).encode())


if __name__ == "__main__":
    main()

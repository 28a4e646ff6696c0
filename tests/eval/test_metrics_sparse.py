"""Evaluation time and memory follow the boxes in the files, not the largest frame number."""
from __future__ import annotations

import math

import numpy as np

from fastdet.eval.metrics import evaluate
from fastdet.io.motfiles import parse_gt, parse_predictions


def _files(frames: list[int]) -> tuple[str, str]:
    rng = np.random.default_rng(1)
    gt, pred = [], []
    for f in frames:
        for tid in (1, 2):
            x, y = 100 * tid + f % 7, 50 + 3 * tid
            gt.append(f"{f},{tid},{x},{y},40,30,1,1,1")
            dx = int(rng.integers(-3, 4))
            pid = tid if f % 5 else 3 - tid  # some id switches
            pred.append(f"{f},{pid},{x + dx},{y},40,30,{rng.uniform(0.1, 1):.3f},-1,-1,-1")
    return "\n".join(gt), "\n".join(pred)


def test_gaps_between_frames_change_no_metric():
    # the same boxes: the second pair's frames 1000.. carry what frames 11.. carry in the first
    d_gt, d_pred = _files(list(range(1, 21)))
    s_gt = "\n".join(ln.replace(f"{f},", f"{f + 989},", 1) if (f := int(ln.split(",")[0])) > 10 else ln
                     for ln in d_gt.splitlines())
    s_pred = "\n".join(ln.replace(f"{f},", f"{f + 989},", 1) if (f := int(ln.split(",")[0])) > 10 else ln
                       for ln in d_pred.splitlines())
    a = evaluate(parse_gt(d_gt), parse_predictions(d_pred)).to_dict()
    b = evaluate(parse_gt(s_gt), parse_predictions(s_pred)).to_dict()
    for k in ("tp", "fp", "fn", "precision", "recall", "f1", "ap", "mota", "motp", "idf1", "id_switches",
              "hota", "deta", "assa"):
        va, vb = a[k], b[k]
        assert (math.isnan(va) and math.isnan(vb)) or va == vb, k


def test_one_line_at_frame_100_million_visits_two_frames(monkeypatch):
    import motmetrics as mm

    seen: list[int] = []
    update = mm.MOTAccumulator.update

    def counting(self, *a, **kw):
        seen.append(kw.get("frameid"))
        return update(self, *a, **kw)

    monkeypatch.setattr(mm.MOTAccumulator, "update", counting)
    gt = parse_gt("1,1,10,10,40,30\n100000000,1,10,10,40,30", "g.txt")
    preds = parse_predictions("1,1,10,10,40,30,0.9\n100000000,1,12,10,40,30,0.8", "p.txt")
    r = evaluate(gt, preds)
    assert r.tp == 2 and r.frames == 100000000 and r.idf1 == 1.0
    assert seen == [1, 100000000]  # was: every frame number from 1 to 10**8 (no result in 300 s)

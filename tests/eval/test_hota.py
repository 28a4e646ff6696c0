"""MOT metrics of ``fastdet.eval``: MOTA, IDF1, id switches, fragmentations (py-motmetrics)
and HOTA / DetA / AssA (fastdet.eval.hota), on hand-made tracks whose answers are worked
out by hand in each test."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastdet.detections import Detections
from fastdet.eval.hota import ALPHAS, hota
from fastdet.eval.metrics import evaluate
from fastdet.eval.report import format_table


def _box(x: float, w: float = 40.0, y: float = 100.0, h: float = 20.0) -> list[float]:
    return [x, y, x + w, y + h]


def _gt(rows: list[tuple[int, int, list[float]]]) -> Detections:
    return Detections(np.array([r[2] for r in rows], float), frames=np.array([r[0] for r in rows]),
                      ids=np.array([r[1] for r in rows]), consider=np.ones(len(rows), bool))


def _pred(rows: list[tuple[int, int, list[float]]]) -> Detections:
    return Detections(np.array([r[2] for r in rows], float), np.ones(len(rows)),
                      frames=np.array([r[0] for r in rows]), ids=np.array([r[1] for r in rows]))


def _car(gid: int, x0: float, frames=range(1, 11), dx: float = 10.0) -> list[tuple[int, int, list[float]]]:
    """A target ``gid`` moving ``dx`` px per frame from ``x0``."""
    return [(f, gid, _box(x0 + dx * (f - 1))) for f in frames]


def _frames(gt_rows, pred_rows):
    """``hota`` input from row lists (every frame that has a row)."""
    fs = sorted({r[0] for r in gt_rows} | {r[0] for r in pred_rows})
    out = []
    for f in fs:
        g = [r for r in gt_rows if r[0] == f]
        p = [r for r in pred_rows if r[0] == f]
        out.append(([r[1] for r in g], [r[2] for r in g], [r[1] for r in p], [r[2] for r in p]))
    return out


def test_perfect_tracking_scores_one():
    gt = _car(1, 0) + _car(2, 300)
    pred = [(f, {1: 7, 2: 9}[g], b) for f, g, b in gt]
    r = evaluate(_gt(gt), _pred(pred))
    assert r.has_tracking
    assert (r.mota, r.idf1, r.id_switches, r.fragmentations) == (1.0, 1.0, 0, 0)
    assert r.hota == pytest.approx(1.0) and r.deta == pytest.approx(1.0) and r.assa == pytest.approx(1.0)


def test_one_id_switch_halfway_one_target():
    # one target, 10 frames, found every frame: id 5 for frames 1-5, id 6 for 6-10.
    # DetA = 1 (10 TP). Pairs (g, 5) and (g, 6): 5 matches each; association Jaccard
    # 5 / (10 + 5 - 5) = 0.5 each, so AssA = (5 * 0.5 + 5 * 0.5) / 10 = 0.5 at every alpha,
    # HOTA = sqrt(1 * 0.5). IDF1: best one-to-one map g -> 5: IDTP 5, IDFN 5, IDFP 5 -> 0.5.
    # MOTA = 1 - (0 FN + 0 FP + 1 switch) / 10.
    gt = _car(1, 0)
    pred = [(f, 5 if f <= 5 else 6, b) for f, _, b in gt]
    r = evaluate(_gt(gt), _pred(pred))
    assert r.id_switches == 1
    assert r.mota == pytest.approx(0.9)
    assert r.idf1 == pytest.approx(0.5)
    assert r.deta == pytest.approx(1.0)
    assert r.assa == pytest.approx(0.5)
    assert r.hota == pytest.approx(math.sqrt(0.5))


def test_two_targets_swap_ids_halfway():
    # targets 1 and 2 far apart; predictions A follows 1 then 2, B follows 2 then 1 (swap after
    # frame 5). Four pairs with 5 matches each, n_g = n_p = 10: Jaccard 5 / (10 + 10 - 5) = 1/3,
    # AssA = 1/3, DetA = 1, HOTA = sqrt(1/3). Two switches (one per target) -> MOTA
    # 1 - 2/20. IDF1: any map gives IDTP 10 of 20 boxes each side -> 0.5.
    t1, t2 = _car(1, 0), _car(2, 400)
    pred = ([(f, 11 if f <= 5 else 12, b) for f, _, b in t1]
            + [(f, 12 if f <= 5 else 11, b) for f, _, b in t2])
    r = evaluate(_gt(t1 + t2), _pred(pred))
    assert r.id_switches == 2
    assert r.mota == pytest.approx(0.9)
    assert r.idf1 == pytest.approx(0.5)
    assert r.assa == pytest.approx(1 / 3)
    assert r.hota == pytest.approx(math.sqrt(1 / 3))


def test_localisation_below_some_thresholds():
    # every prediction has IoU 0.62 with its target (62 of 100 px wide, same rows): a TP for
    # the 12 thresholds 0.05 .. 0.60, nothing for 0.65 .. 0.95 (DetA = AssA = 0 there).
    # HOTA = DetA = AssA = 12 / 19. LocA is 0.62 where there are TPs and 1 where there are
    # none (TrackEval's convention), so its mean is (12 * 0.62 + 7) / 19.
    gt = [(f, 1, [0.0, 0.0, 100.0, 10.0]) for f in range(1, 6)]
    pred = [(f, 3, [0.0, 0.0, 62.0, 10.0]) for f in range(1, 6)]
    h = hota(_frames(gt, pred))
    assert h.hota == pytest.approx(12 / 19)
    assert h.deta == pytest.approx(12 / 19)
    assert h.assa == pytest.approx(12 / 19)
    assert h.loca == pytest.approx((12 * 0.62 + 7) / 19)
    np.testing.assert_allclose(h.per_alpha["deta"], (ALPHAS < 0.62).astype(float))


def test_missed_frames_fragment_a_track():
    # found in frames 1-4 and 7-10 with one id, missed in 5 and 6: 8 TP, 2 FN.
    # DetA = 8/10; AssA: c = 8, n_g = 10, n_p = 8, Jaccard 8 / (10 + 8 - 8) = 0.8; HOTA 0.8.
    # One fragmentation; MOTA = 1 - 2/10; IDF1 = 2*8 / (2*8 + 0 + 2).
    gt = _car(1, 0)
    pred = [(f, 4, b) for f, _, b in gt if f not in (5, 6)]
    r = evaluate(_gt(gt), _pred(pred))
    assert r.fragmentations == 1
    assert r.id_switches == 0
    assert r.mota == pytest.approx(0.8)
    assert r.idf1 == pytest.approx(16 / 18)
    assert r.deta == pytest.approx(0.8)
    assert r.assa == pytest.approx(0.8)
    assert r.hota == pytest.approx(0.8)


def test_false_track_lowers_detection_not_association():
    # a perfect track plus a false track of 5 boxes where nothing is: DetA = 10 / (10 + 5);
    # AssA = 1 (the only TP pair is perfectly associated); HOTA = sqrt(2/3). MOTA 1 - 5/10.
    gt = _car(1, 0)
    pred = [(f, 1, b) for f, _, b in gt] + [(f, 2, _box(600)) for f in range(1, 6)]
    r = evaluate(_gt(gt), _pred(pred))
    assert r.deta == pytest.approx(10 / 15)
    assert r.assa == pytest.approx(1.0)
    assert r.hota == pytest.approx(math.sqrt(2 / 3))
    assert r.mota == pytest.approx(0.5)


def test_hota_symmetric_and_label_free():
    # HOTA treats targets and predictions alike, and does not care what the ids are.
    rng = np.random.default_rng(0)
    gt, pred = [], []
    for f in range(1, 16):
        for g in range(3):
            if rng.random() < 0.85:
                gt.append((f, g + 1, _box(150 * g + 3 * f)))
            if rng.random() < 0.8:
                jitter = rng.normal(0, 4, 4)
                pid = (g + 1) * 10 + (f > 8 and g == 1)  # target 2's track breaks at frame 9
                pred.append((f, pid, list(np.array(_box(150 * g + 3 * f)) + jitter)))
    a = hota(_frames(gt, pred))
    b = hota(_frames(pred, gt))
    c = hota(_frames(gt, [(f, 1000 - i, bx) for f, i, bx in pred]))
    assert 0 < a.hota < 1
    assert b.hota == pytest.approx(a.hota) and b.deta == pytest.approx(a.deta) and b.assa == pytest.approx(a.assa)
    assert c.hota == pytest.approx(a.hota)


def test_no_predictions_and_no_targets():
    h = hota(_frames(_car(1, 0), []))
    assert (h.hota, h.deta, h.assa) == (0.0, 0.0, 0.0)
    h = hota([])
    assert h.hota == 0.0


def test_untracked_predictions_have_no_mot_metrics_and_table_lists_them():
    gt = _car(1, 0)
    untracked = _pred([(f, -1, b) for f, _, b in gt])
    r = evaluate(_gt(gt), untracked)
    assert not r.has_tracking and r.hota is None and "hota" not in r.to_dict()
    tracked = evaluate(_gt(gt), _pred([(f, 1, b) for f, _, b in gt]))
    table = format_table(tracked)
    for name in ("MOTA", "IDF1", "ID switches", "fragmentations", "HOTA", "DetA", "AssA"):
        assert name in table
    d = tracked.to_dict()
    assert d["hota"] == pytest.approx(1.0) and d["fragmentations"] == 0


def test_hota_memory_follows_the_matched_pairs_not_the_id_pairs():
    """issue 34, item 10: ``(19, n_gt_ids, n_pred_ids)`` counts were allocated dense (5.6 GB for
    5,000 + 5,000 ids); 2,000 + 2,000 ids, one box each on a frame of its own, took 600 MB, and
    500 + 500 (here: tracemalloc makes every allocation slow) would take 38 MB dense; now about
    2 MB."""
    import tracemalloc
    n = 500
    frames = [(np.array([k]), np.array([_box(10.0)]), np.array([k]), np.array([_box(12.0)])) for k in range(n)]
    tracemalloc.start()
    r = hota(frames)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 10 * 2**20, peak
    assert r.deta > 0.9 and r.assa > 0.9


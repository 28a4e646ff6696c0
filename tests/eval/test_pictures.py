"""fastdet.eval.pictures: per-source scores of labelled pictures, against a slow, obvious
reference (greedy matching per picture, written out plainly here) on random boxes, and on
real pictures of the shared data."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.detections import Detections
from fastdet.eval.pictures import SourceScore, markdown_rows, score_pictures, score_source
from fastdet.labels import AnnotatedPicture


def _iou(a, b) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def _inter(a, b) -> float:
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def reference(pictures, preds, iou=0.5):
    """Plain per-picture greedy matching: (tp, fp, dropped, ranked hit flags, found per target)."""
    tp = fp = dropped = 0
    ranked = []  # (score, picture index, prediction index, hit) of the counted predictions
    found = []
    for i, (pic, pred) in enumerate(zip(pictures, preds)):
        order = sorted(range(len(pred.scores)), key=lambda k: -float(pred.scores[k]))
        taken = [False] * len(pic.targets)
        for k in order:
            box = [float(v) for v in pred.boxes[k]]
            best, best_j = -1.0, -1
            for j, t in enumerate(pic.targets):
                if not taken[j]:
                    v = _iou(box, t)
                    if v > best:
                        best, best_j = v, j
            if best_j >= 0 and best >= iou:
                taken[best_j] = True
                tp += 1
                if pic.complete:
                    ranked.append((-float(pred.scores[k]), i, k, True))
                continue
            a = (box[2] - box[0]) * (box[3] - box[1])
            if a > 0 and any(_inter(box, g) >= 0.5 * a for g in pic.ignores):
                dropped += 1
                continue
            if pic.complete:
                fp += 1
                ranked.append((-float(pred.scores[k]), i, k, False))
        found += taken
    ranked.sort(key=lambda r: (r[0], r[1], r[2]))
    return tp, fp, dropped, [r[3] for r in ranked], found


def reference_ap(hits, n_targets):
    """All-point AP the long way: precision at each rank, the envelope, summed over recall steps."""
    if n_targets == 0:
        return math.nan
    ap, ctp, prev_r = 0.0, 0, 0.0
    precisions = []
    for k, h in enumerate(hits):
        ctp += h
        precisions.append(ctp / (k + 1))
    ctp = 0
    for k, h in enumerate(hits):
        ctp += h
        r = ctp / n_targets
        if r > prev_r:
            ap += (r - prev_r) * max(precisions[k:])
            prev_r = r
    return ap


coord = st.integers(0, 60)


@st.composite
def box(draw):
    x, y = draw(coord), draw(coord)
    return [x, y, x + draw(st.integers(1, 30)), y + draw(st.integers(1, 30))]


@st.composite
def picture(draw, complete=None):
    targets = draw(st.lists(box(), max_size=4))
    ignores = draw(st.lists(box(), max_size=2))
    preds = draw(st.lists(box(), max_size=6))
    # near-copies of targets so that hits happen
    preds += [[t[0] + draw(st.integers(-3, 3)), t[1], t[2], t[3] + draw(st.integers(-3, 3))]
              for t in targets if draw(st.booleans())]
    preds = [p for p in preds if p[2] > p[0] and p[3] > p[1]]
    scores = draw(st.lists(st.sampled_from([0.1, 0.5, 0.7, 0.9, 2.0]), min_size=len(preds), max_size=len(preds)))
    comp = draw(st.booleans()) if complete is None else complete
    pic = AnnotatedPicture("s", "cam", "p.jpg", Path("p.jpg"), 100, 100, targets, ignores, complete=comp)
    return pic, Detections(np.array(preds, np.int32).reshape(-1, 4), np.array(scores, np.float32))


def _check(pics, preds):
    got = score_source("s", pics, preds)
    tp, fp, dropped, hits, found = reference(pics, preds)
    n = sum(len(p.targets) for p in pics)
    assert (got.tp, got.dropped, got.targets) == (tp, dropped, n)
    assert got.recall == pytest.approx(tp / n) if n else math.isnan(got.recall)
    if got.complete:
        assert got.fp == fp
        assert list(got.ranked_tp) == hits
        ap = reference_ap(hits, n)
        assert (math.isnan(got.ap) and math.isnan(ap)) or got.ap == pytest.approx(ap)
        assert got.f1 == pytest.approx(2 * tp / (2 * tp + fp + n - tp)) if (tp + fp + n) else True
        assert got.fa_per_picture == pytest.approx(fp / len(pics))
    else:
        assert math.isnan(got.precision) and math.isnan(got.ap) and math.isnan(got.f1)
        assert math.isnan(got.fa_per_picture)
    # every target is in one width bin (the pictures are 100 px wide: x12.8 reference px)
    assert sum(b.total for b in got.widths) == n
    assert sum(b.found for b in got.widths) == sum(found)


@settings(max_examples=150, deadline=None)
@given(st.lists(picture(complete=True), min_size=1, max_size=5))
def test_complete_sets_match_the_reference(items):
    _check([p for p, _ in items], [d for _, d in items])


@settings(max_examples=100, deadline=None)
@given(st.lists(picture(), min_size=1, max_size=5))
def test_partial_sets_count_no_false_alarms(items):
    pics, preds = [p for p, _ in items], [d for _, d in items]
    _check(pics, preds)
    got = score_source("s", pics, preds)
    assert got.complete == all(p.complete for p in pics)
    # false alarms of the complete pictures only
    assert got.fp == reference([p for p in pics if p.complete], [d for p, d in items if p.complete])[1]


def test_a_detection_on_an_ignore_region_counts_neither_way():
    pic = AnnotatedPicture("s", "c", "a.jpg", Path("a.jpg"), 640, 360, [[0, 0, 100, 100]], [[300, 100, 340, 130]])
    pred = Detections(np.array([[302, 102, 338, 128], [500, 200, 560, 260]], np.int32),
                      np.array([0.9, 0.8], np.float32))
    s = score_source("s", [pic], [pred])
    assert (s.tp, s.fp, s.dropped, s.targets) == (0, 1, 1, 1)
    assert s.precision == 0.0 and s.recall == 0.0


def test_recall_only_rows_say_so():
    pic = AnnotatedPicture("w", "c", "a.jpg", Path("a.jpg"), 1280, 720, [[0, 0, 100, 100]], complete=False)
    s = score_source("w", [pic], [Detections(np.array([[0, 0, 100, 100], [500, 0, 600, 100]], np.int32),
                                             np.array([1.0, 1.0], np.float32))])
    assert isinstance(s, SourceScore) and s.recall == 1.0 and s.fp == 0
    row = markdown_rows([s])[0]
    assert "recall only" in row and "n/a" in row
    assert s.to_dict()["precision"] is None and s.to_dict()["fp"] is None


def test_lengths_must_agree():
    with pytest.raises(ValueError):
        score_source("s", [], [Detections.empty()])


def test_real_pictures_against_the_reference(data):
    """kitti_tiny and dawn_weather (partial) read by the shared-set reader, scored with boxes
    made from the labels (moved, dropped, plus false ones): the scorer agrees with the reference."""
    from fastdet.labels.sets import shared_sets

    sets = shared_sets(data)
    rng = np.random.default_rng(0)
    for name in ("kitti_tiny", "dawn_weather"):
        pics = sets[name][:20]
        preds = []
        for p in pics:
            t = p.targets[rng.random(len(p.targets)) < 0.7]
            t = t + rng.integers(-6, 7, t.shape)
            extra = rng.integers(0, 300, (2, 2))
            extra = np.concatenate([extra, extra + 60], axis=1)
            b = np.concatenate([t, extra]).astype(np.int32)
            preds.append(Detections(b, rng.random(len(b)).astype(np.float32)))
        _check(pics, preds)


def test_score_pictures_loads_and_detects(data):
    from fastdet.labels.sets import shared_sets

    pics = shared_sets(data)["kitti_tiny"][:3]
    seen = []

    def detect(img):
        seen.append(img.shape)
        return Detections.empty()

    s = score_pictures("kitti_tiny", pics, detect)
    assert seen == [(p.height, p.width, 3) for p in pics]
    assert s.tp == 0 and s.recall == 0.0 and s.seconds >= 0

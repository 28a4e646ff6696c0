"""fastdet.eval / fastdet.motio on hand-made cases with answers worked out by hand."""
from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

from fastdet.boxes import iou as box_iou
from fastdet.cli import eval as ev
from fastdet.cli import main
from fastdet.detections import Detections
from fastdet.errors import DataError, FastdetError
from fastdet.eval import average_precision, evaluate, format_table, match_frame
from fastdet.io.motfiles import (
    JsonLinesWriter,
    MotWriter,
    parse_gt,
    parse_predictions,
    read_gt,
    read_predictions,
)


def gt_of(*rows) -> Detections:
    """rows: (frame, id, left, top, width, height, consider)."""
    return parse_gt("\n".join(",".join(str(v) for v in r) + ",1,1" for r in rows), "gt")


def pred_of(*rows) -> Detections:
    """rows: (frame, id, left, top, width, height, conf)."""
    return parse_predictions("\n".join(",".join(str(v) for v in r) + ",-1,-1,-1" for r in rows), "pred")


# two frames, two targets each, one ignore region in frame 1
GT_ROWS = [
    (1, 1, 100, 100, 50, 40, 1),
    (1, 2, 300, 100, 60, 40, 1),
    (1, 9, 600, 100, 20, 10, 0),
    (2, 1, 105, 100, 50, 40, 1),
    (2, 2, 310, 100, 60, 40, 1),
]


def perfect_preds(ids: bool = False) -> Detections:
    rows = [(f, i if ids else -1, l, t, w, h, 0.9 - 0.1 * k)
            for k, (f, i, l, t, w, h, c) in enumerate(GT_ROWS) if c == 1]
    return pred_of(*rows)


def test_iou_basics():
    a = np.array([[0, 0, 10, 10]], float)
    b = np.array([[0, 0, 10, 10], [5, 0, 15, 10], [20, 20, 30, 30], [0, 0, 10, 5]], float)
    np.testing.assert_allclose(box_iou(a, b), [[1.0, 50 / 150, 0.0, 0.5]])


def test_perfect_predictions():
    r = evaluate(gt_of(*GT_ROWS), perfect_preds())
    assert (r.frames, r.num_gt, r.num_ignore, r.tp, r.fp, r.fn) == (2, 4, 1, 4, 0, 0)
    assert r.precision == r.recall == r.f1 == r.ap == 1.0
    assert r.fp_per_frame == 0.0
    assert not r.has_tracking
    assert "mota" not in r.to_dict()


def test_one_missed_box():
    gt = gt_of(*GT_ROWS)
    p = pred_of((1, -1, 100, 100, 50, 40, 0.9), (1, -1, 300, 100, 60, 40, 0.8), (2, -1, 105, 100, 50, 40, 0.7))
    r = evaluate(gt, p)
    assert (r.tp, r.fp, r.fn) == (3, 0, 1)
    assert r.precision == 1.0
    assert r.recall == pytest.approx(0.75)
    assert r.f1 == pytest.approx(2 * 3 / (2 * 3 + 0 + 1))
    assert r.ap == pytest.approx(0.75)


def test_one_false_positive_ranked_first():
    gt = gt_of((1, 1, 0, 0, 10, 10, 1), (1, 2, 50, 0, 10, 10, 1))
    p = pred_of((1, -1, 200, 200, 10, 10, 0.99), (1, -1, 0, 0, 10, 10, 0.5), (1, -1, 50, 0, 10, 10, 0.4))
    r = evaluate(gt, p)
    assert (r.tp, r.fp, r.fn) == (2, 1, 0)
    assert r.precision == pytest.approx(2 / 3)
    assert r.recall == 1.0
    assert r.fp_per_frame == 1.0
    # ranks FP, TP, TP: precision 0, 1/2, 2/3 at recall 0, 1/2, 1 -> envelope 2/3 everywhere
    assert r.ap == pytest.approx(2 / 3)
    np.testing.assert_allclose(r.pr_recall, [0, 0.5, 1])
    np.testing.assert_allclose(r.pr_precision, [0, 0.5, 2 / 3])
    np.testing.assert_allclose(r.pr_scores, [0.99, 0.5, 0.4])


def test_detection_on_ignore_region_is_dropped():
    gt = gt_of(*GT_ROWS)
    extra = [
        (1, -1, 600, 100, 20, 10, 0.95),  # exactly the ignore region: dropped
        (1, -1, 610, 100, 20, 10, 0.94),  # half of its area on it: dropped (>= 0.5)
        (1, -1, 611, 100, 20, 10, 0.93),  # 45 % on it: a false positive
        (2, -1, 600, 100, 20, 10, 0.92),  # no ignore region in frame 2: false positive
    ]
    base = [(f, -1, l, t, w, h, 0.5) for (f, i, l, t, w, h, c) in GT_ROWS if c == 1]
    r = evaluate(gt, pred_of(*base, *extra))
    assert (r.tp, r.fp, r.fn, r.num_dropped, r.num_pred) == (4, 2, 0, 2, 8)
    assert r.pr_scores.size == 6  # dropped predictions are not ranked


def test_two_predictions_on_one_gt():
    gt = gt_of((1, 1, 0, 0, 100, 100, 1))
    # the better-placed box has the lower score: greedy by confidence gives the GT to the other
    p = pred_of((1, -1, 0, 0, 100, 100, 0.6), (1, -1, 10, 0, 100, 100, 0.9))
    r = evaluate(gt, p)
    assert (r.tp, r.fp, r.fn) == (1, 1, 0)
    np.testing.assert_allclose(r.pr_scores, [0.9, 0.6])
    np.testing.assert_allclose(r.pr_precision, [1.0, 0.5])
    assert r.ap == 1.0
    tp, _, gi = match_frame(p.boxes, p.scores, gt.boxes)
    assert tp.tolist() == [False, True] and gi.tolist() == [-1, 0]


def test_prediction_takes_best_unmatched_gt():
    gt = gt_of((1, 1, 0, 0, 100, 100, 1), (1, 2, 20, 0, 100, 100, 1))
    # first (highest score) is closest to GT 2; second overlaps both, GT 1 still free
    p = pred_of((1, -1, 20, 0, 100, 100, 0.9), (1, -1, 10, 0, 100, 100, 0.8))
    r = evaluate(gt, p)
    assert (r.tp, r.fp, r.fn) == (2, 0, 0)


def test_ap_of_known_ranking():
    # 3 targets over two frames; ranking TP(0.9) FP(0.8) TP(0.7) FP(0.6), one target missed.
    gt = gt_of((1, 1, 0, 0, 10, 10, 1), (1, 2, 100, 0, 10, 10, 1), (2, 1, 0, 0, 10, 10, 1))
    p = pred_of(
        (2, -1, 0, 0, 10, 10, 0.9),
        (1, -1, 300, 0, 10, 10, 0.8),
        (1, -1, 0, 0, 10, 10, 0.7),
        (2, -1, 300, 0, 10, 10, 0.6),
    )
    r = evaluate(gt, p)
    # precision 1, 1/2, 2/3, 1/2 at recall 1/3, 1/3, 2/3, 2/3: AP = 1/3 * 1 + 1/3 * 2/3
    assert r.ap == pytest.approx(5 / 9)
    ap, rec, prec = average_precision(np.array([True, False, True, False]), 3)
    assert ap == pytest.approx(5 / 9)
    np.testing.assert_allclose(prec, [1, 0.5, 2 / 3, 0.5])


def test_ap_edge_cases():
    assert average_precision(np.zeros(0, bool), 4)[0] == 0.0
    assert math.isnan(average_precision(np.array([False]), 0)[0])
    r = evaluate(gt_of((1, 1, 0, 0, 10, 10, 1)), Detections.from_frames([]))
    assert r.ap == 0.0 and r.recall == 0.0 and math.isnan(r.precision) and r.f1 == 0.0
    assert r.to_dict()["precision"] is None
    assert "n/a" in format_table(r)


def test_iou_threshold_edge():
    gt = gt_of((1, 1, 0, 0, 10, 10, 1))
    p = pred_of((1, -1, 0, 0, 10, 5, 0.9))  # IoU exactly 0.5
    assert evaluate(gt, p, iou=0.5).tp == 1
    assert evaluate(gt, p, iou=0.51).tp == 0
    p2 = pred_of((1, -1, 0, 0, 10, 4.9, 0.9))
    assert evaluate(gt, p2, iou=0.5).tp == 0
    with pytest.raises(ValueError):
        evaluate(gt, p, iou=0.0)


def test_frame_range():
    # GT on frames 1 and 3: frame 2 is evaluated (an empty frame), frame 4 is not
    gt = gt_of((1, 1, 0, 0, 10, 10, 1), (3, 1, 0, 0, 10, 10, 1))
    p = pred_of((2, -1, 0, 0, 10, 10, 0.9), (4, -1, 0, 0, 10, 10, 0.9), (3, -1, 0, 0, 10, 10, 0.8))
    r = evaluate(gt, p)
    assert (r.frames, r.tp, r.fp, r.fn, r.num_outside, r.num_pred) == (3, 1, 1, 1, 1, 2)
    assert r.fp_per_frame == pytest.approx(1 / 3)
    assert "not evaluated" in format_table(r)
    assert evaluate(gt, p, num_frames=4).fp == 2


# ---------------------------------------------------------------------------------------
# malformed input


@pytest.mark.parametrize(
    "line, words",
    [
        ("1,1,10,10,20,20", None),  # 6 columns is fine for GT
        ("1,1,10,10,20", ["line 2", "columns"]),
        ("1,1,10,10,20,20,1,1,1,1,1", ["line 2", "columns"]),
        ("1,1,abc,10,20,20,1,1,1", ["line 2", "left", "abc"]),
        ("1,1,10,10,-20,20,1,1,1", ["line 2", "negative"]),
        ("0,1,10,10,20,20,1,1,1", ["line 2", "frame"]),
        ("1.5,1,10,10,20,20,1,1,1", ["line 2", "whole"]),
        ("1,1,10,10,20,20,2,1,1", ["line 2", "consider"]),
        ("1,1,nan,10,20,20,1,1,1", ["line 2", "finite"]),
    ],
)
def test_malformed_gt(tmp_path, line, words):
    f = tmp_path / "bad_gt.txt"
    f.write_text("1,1,10,10,20,20,1,1,1\n" + line + "\n\n")
    if words is None:
        assert len(read_gt(f)) == 2
        return
    with pytest.raises(DataError) as ei:
        read_gt(f)
    msg = str(ei.value)
    assert "bad_gt.txt" in msg
    for w in words:
        assert w in msg


def test_malformed_predictions_and_missing_files(tmp_path):
    f = tmp_path / "pred.txt"
    f.write_text("\n1,-1,10,10,20,20,0.5,-1,-1,-1\n\n1,-1,10,10,20,20\n")
    with pytest.raises(DataError, match=r"pred\.txt: line 4: expected 7 to 10"):
        read_predictions(f)
    f.write_text("1,-1,10,10,20,20,high,-1,-1,-1\n")
    with pytest.raises(DataError, match=r"pred\.txt: line 1: conf is not a number"):
        read_predictions(f)
    with pytest.raises(DataError, match="nope.txt"):
        read_gt(tmp_path / "nope.txt")
    with pytest.raises(DataError, match="nope.txt"):
        read_predictions(tmp_path / "nope.txt")
    empty = tmp_path / "empty.txt"
    empty.write_text("\n")
    assert len(read_predictions(empty)) == 0  # a detector that found nothing
    with pytest.raises(DataError, match="empty.txt"):
        read_gt(empty)


# ---------------------------------------------------------------------------------------
# writers


def test_mot_and_jsonl_writers_round_trip(tmp_path):
    frames = [
        (1, Detections(np.array([[10, 20, 60, 70], [100, 100, 140, 130]], np.int32),
                       np.array([0.9, 0.25], np.float32))),
        (2, Detections.empty()),
        (3, Detections(np.array([[5, 5, 15, 25]], np.int32), np.array([1.5], np.float32))),
    ]
    mot, jl = tmp_path / "out.txt", tmp_path / "out.jsonl"
    with MotWriter(mot) as w1, JsonLinesWriter(jl) as w2:
        for f, d in frames:
            w1.write_detections(f, d)
            w2.write(f, d.boxes, d.scores)
        w1.write(4, [[0, 0, 10, 10]], [0.5], ids=[7])
        w2.write(4, [[0, 0, 10, 10]], [0.5], ids=[7])
    lines = mot.read_text().splitlines()
    assert lines[0] == "1,-1,10,20,50,50,0.9,-1,-1,-1"
    assert lines[-1] == "4,7,0,0,10,10,0.5,-1,-1,-1"
    objs = [json.loads(s) for s in jl.read_text().splitlines()]
    assert [o["frame"] for o in objs] == [1, 2, 3, 4]
    assert objs[0] == {"frame": 1, "boxes": [[10, 20, 60, 70], [100, 100, 140, 130]], "scores": [0.9, 0.25],
                       "ids": [-1, -1]}
    for path in (mot, jl):
        p = read_predictions(path)
        assert p.frames.tolist() == [1, 1, 3, 4]
        assert p.ids.tolist() == [-1, -1, -1, 7]
        np.testing.assert_array_equal(p.boxes, [[10, 20, 60, 70], [100, 100, 140, 130], [5, 5, 15, 25], [0, 0, 10, 10]])
        np.testing.assert_allclose(p.scores, [0.9, 0.25, 1.5, 0.5], rtol=1e-6)


# ---------------------------------------------------------------------------------------
# MOT metrics


def test_perfect_tracks():
    r = evaluate(gt_of(*GT_ROWS), perfect_preds(ids=True))
    assert r.has_tracking
    assert r.mota == 1.0 and r.idf1 == 1.0 and r.id_switches == 0 and r.motp == pytest.approx(0.0)
    d = r.to_dict()
    assert d["mota"] == 1.0 and d["id_switches"] == 0
    assert "MOTA" in format_table(r) and "IDF1" in format_table(r)


def test_one_id_switch():
    gt = gt_of(*[(f, 1, 10 * f, 0, 50, 50, 1) for f in range(1, 5)])
    p = pred_of(*[(f, 7 if f <= 2 else 8, 10 * f, 0, 50, 50, 0.9) for f in range(1, 5)])
    r = evaluate(gt, p)
    assert (r.tp, r.fp, r.fn) == (4, 0, 0)
    assert r.id_switches == 1
    assert r.mota == pytest.approx(1 - 1 / 4)
    assert r.idf1 == pytest.approx(0.5)


def test_tracking_ignores_dropped_and_needs_unique_ids():
    gt = gt_of((1, 1, 0, 0, 50, 50, 1), (1, 2, 200, 0, 20, 10, 0))
    p = pred_of((1, 5, 0, 0, 50, 50, 0.9), (1, 6, 200, 0, 20, 10, 0.9))  # second one dropped
    r = evaluate(gt, p)
    assert r.num_dropped == 1 and r.mota == 1.0
    with pytest.raises(DataError, match="appears twice in frame 1"):
        evaluate(gt, pred_of((1, 5, 0, 0, 50, 50, 0.9), (1, 5, 300, 0, 50, 50, 0.9)))


# ---------------------------------------------------------------------------------------
# CLI


@pytest.fixture()
def files(tmp_path):
    gt = tmp_path / "gt.txt"
    gt.write_text("".join(",".join(str(v) for v in r) + ",1,1\n" for r in GT_ROWS))
    pred = tmp_path / "pred.txt"
    with MotWriter(pred) as w:
        for f in (1, 2):
            rows = [r for r in GT_ROWS if r[0] == f and r[6] == 1]
            w.write(f, [[l, t, l + wd, t + h] for (_, _, l, t, wd, h, _) in rows], [0.8] * len(rows))
        w.write(2, [[500, 500, 520, 520]], [0.3])
    return gt, pred


def test_cli_table(files, capsys):
    gt, pred = files
    assert main(["eval", "--gt", str(gt), "--pred", str(pred)]) == 0
    out = capsys.readouterr().out
    for word in ("frames", "GT boxes", "TP", "FP", "FN", "precision", "recall", "F1", "FP per frame", "AP"):
        assert word in out
    assert "0.8000" in out  # precision 4/5
    assert "MOTA" not in out


def test_cli_json_and_plot(files, tmp_path, capsys):
    gt, pred = files
    png = tmp_path / "pr.png"
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--json", "--iou", "0.7", "--plot", str(png)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["tp"], d["fp"], d["fn"], d["frames"]) == (4, 1, 0, 2)
    assert d["precision"] == pytest.approx(0.8) and d["ap"] == 1.0 and d["iou_threshold"] == 0.7
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    import cv2

    img = cv2.imread(str(png))
    assert img is not None and img.ndim == 3 and img.shape[0] > 200
    assert not list(tmp_path.glob(".pr-*"))  # no temporary left behind


def test_cli_mot_metrics(tmp_path, capsys):
    gt = tmp_path / "gt.txt"
    gt.write_text("".join(",".join(str(v) for v in r) + ",1,1\n" for r in GT_ROWS))
    pred = tmp_path / "tracks.txt"
    pred.write_text("".join(f"{f},{i},{l},{t},{w},{h},0.9,-1,-1,-1\n" for (f, i, l, t, w, h, c) in GT_ROWS if c))
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["mota"] == 1.0 and d["idf1"] == 1.0 and d["id_switches"] == 0


def test_cli_errors(files, tmp_path, capsys):
    gt, pred = files
    bad = tmp_path / "broken.txt"
    bad.write_text("1,-1,1,1,5,5,0.5,-1,-1,-1\n1,-1,1,1,-5,5,0.5,-1,-1,-1\n")
    assert main(["eval", "--gt", str(gt), "--pred", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "broken.txt: line 2" in err and len(err.strip().splitlines()) == 1
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--model", "m.npz"]) == 2
    assert "--model" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["eval", "--gt", str(gt), "--pred", str(pred), "--iou", "1.5"])


def _parse(argv):
    p = argparse.ArgumentParser()
    ev.add_arguments(p)
    return p.parse_args(argv)


def test_video_option_uses_pipeline(files, tmp_path, monkeypatch, capsys):
    gt, _ = files
    clip = tmp_path / "clip.mp4"
    clip.write_bytes(b"")
    calls = {}

    def fake_iter(path, config, progress=True, **kw):
        calls.update(path=path, model=config.model, oncoming=config.oncoming)
        for f in (1, 2):
            rows = [r for r in GT_ROWS if r[0] == f and r[6] == 1]
            boxes = np.array([[l, t, l + w, t + h] for (_, _, l, t, w, h, _) in rows], np.int32)
            yield f, Detections(boxes, np.full(len(rows), 0.5, np.float32))

    monkeypatch.setattr(ev, "iter_video_detections", fake_iter)
    assert ev.run(_parse(["--gt", str(gt), "--video", str(clip), "--model", "m.npz", "--json"])) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["ap"] == 1.0 and d["video"] == str(clip)
    assert calls == {"path": str(clip), "model": "m.npz", "oncoming": True}
    assert ev.run(_parse(["--gt", str(gt), "--video", str(clip), "--no-oncoming", "--json"])) == 0
    assert calls["oncoming"] is False
    with pytest.raises(FastdetError, match="only apply with --video"):
        ev.run(_parse(["--gt", str(gt), "--pred", str(gt), "--no-oncoming"]))


# ---------------------------------------------------------------------------------------
# the real annotations


def test_real_annotations_against_themselves(data):
    files = sorted((data / "annotations").glob("*.gt.txt"))
    assert files
    for f in files:
        gt = read_gt(f)
        c = gt.consider
        preds = Detections(gt.boxes[c], np.ones(int(c.sum())), ids=gt.ids[c], frames=gt.frames[c], source=str(f))
        r = evaluate(gt, preds)
        assert r.num_gt == int(c.sum()) > 0
        assert (r.fp, r.fn, r.num_dropped) == (0, 0, 0)
        assert r.precision == r.recall == r.f1 == r.ap == 1.0
        assert r.mota == 1.0 and r.idf1 == 1.0 and r.id_switches == 0


def test_default_pipeline_accuracy_on_the_annotated_clips(data):
    """The accuracy table's defaults row (docs/accuracy.md): `python -m fastdet eval --video CLIP`
    with the bundled models. Guards against accuracy regressions (the figures it gives,
    less a small margin: F1 0.90 / 1.00, FP per frame 0.05 / 0.00)."""
    from fastdet.video import iter_video_detections

    floors = {"test_video": (0.99, 0.01), "test_small1": (0.88, 0.08)}  # min F1, max FP per frame
    for name, (min_f1, max_fp) in floors.items():
        video = data / "videos" / f"{name}.mp4"
        gt = read_gt(data / "annotations" / f"{name}.gt.txt")
        r = evaluate(gt, Detections.from_frames(iter_video_detections(video, progress=False)), iou=0.5)
        assert r.f1 >= min_f1 and r.fp_per_frame <= max_fp, (name, r.f1, r.fp_per_frame)


def test_evaluate_refuses_a_frame_past_the_pair_budget_in_one_line():
    """issue 34, item 10: 15,000 + 15,000 boxes on one frame were OOM-killed at 23.7 GB."""
    import tracemalloc

    from fastdet.eval.metrics import MAX_FRAME_PAIRS, MAX_TRACK_IDS
    from tests.eval.test_hota import _box as hota_box
    from tests.eval.test_hota import _gt as hota_gt
    from tests.eval.test_hota import _pred as hota_pred
    n = 15_000
    xs = np.arange(n, dtype=float)
    gt = hota_gt([(1, k, hota_box(x)) for k, x in enumerate(xs)])
    pred = hota_pred([(1, k, hota_box(x + 1)) for k, x in enumerate(xs)])
    tracemalloc.start()
    with pytest.raises(DataError, match=f"frame 1 holds 15000 ground-truth and 15000 predicted boxes: more than "
                                        f"the {MAX_FRAME_PAIRS} pairs"):
        evaluate(gt, pred)
    assert tracemalloc.get_traced_memory()[1] < 100 * 2**20
    tracemalloc.stop()
    # ids past the MOT metrics' budget, a few boxes a frame
    m = MAX_TRACK_IDS
    gt = hota_gt([(k + 1, k, hota_box(10.0)) for k in range(m)])
    pred = hota_pred([(k + 1, k, hota_box(11.0)) for k in range(m)])
    with pytest.raises(DataError, match=f"would match {2 * m} ground-truth and predicted ids"):
        evaluate(gt, pred)
    assert evaluate(gt, pred, tracking=False).tp == m

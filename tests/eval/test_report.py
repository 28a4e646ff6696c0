"""fastdet/eval/report.py: the metrics table, row by row, and the precision-recall plot (a PNG
written atomically)."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from fastdet.errors import FastdetError
from fastdet.eval.metrics import EvalResult
from fastdet.eval.report import format_table, plot_pr


def _result(**kw) -> EvalResult:
    base = dict(iou_threshold=0.5, frames=2, num_gt=4, num_ignore=1, num_pred=6, num_dropped=1, num_outside=0,
                tp=3, fp=2, fn=1, precision=0.6, recall=0.75, f1=2 * 0.6 * 0.75 / 1.35, fp_per_frame=1.0,
                ap=0.5625, pr_scores=np.array([0.9, 0.8, 0.7, 0.6, 0.5]),
                pr_recall=np.array([0.25, 0.25, 0.5, 0.75, 0.75]),
                pr_precision=np.array([1.0, 0.5, 2 / 3, 0.75, 0.6]))
    return EvalResult(**{**base, **kw})


def _rows(table: str) -> dict[str, str]:
    return {k.strip(): v.strip() for k, v in (line.split("  ", 1) for line in table.splitlines()
                                              if not line.startswith("("))}


def test_table_rows_of_a_detection_result():
    rows = _rows(format_table(_result()))
    assert rows == {"IoU threshold": "0.5", "frames": "2", "GT boxes": "4  (+ 1 ignore regions)",
                    "predictions": "6  (1 dropped on ignore regions)", "TP": "3", "FP": "2", "FN": "1",
                    "precision": "0.6000", "recall": "0.7500", "F1": "0.6667", "FP per frame": "1.000",
                    "AP": "0.5625"}


def test_table_tracking_rows_missing_values_and_frames_left_out():
    r = _result(mota=0.5, motp=0.25, idf1=0.8, id_switches=2, fragmentations=1, hota=0.7, deta=0.6, assa=0.8,
                precision=math.nan, num_outside=3)
    text = format_table(r)
    rows = _rows(text)
    assert rows["precision"] == "n/a"
    assert (rows["MOTA"], rows["MOTP (1 - IoU)"], rows["IDF1"], rows["ID switches"], rows["HOTA"]) == (
        "0.5000", "0.2500", "0.8000", "2", "0.7000")
    assert text.splitlines()[-1] == "(3 predictions after the last GT frame 2 were not evaluated)"
    keyed = format_table(_result(keyframes=True, num_outside=3))
    assert _rows(keyed)["frames"] == "2 keyframes" and "not keyframes" in keyed.splitlines()[-1]
    assert "MOTA" not in format_table(_result())


def test_plot_pr_writes_a_png(tmp_path):
    out = tmp_path / "pr.png"
    plot_pr(_result(), out, title="clip")
    img = cv2.imread(str(out))
    assert img is not None and img.shape == (560, 720, 3)
    assert img.std() > 0  # not a blank picture
    assert [p.name for p in tmp_path.iterdir()] == ["pr.png"]  # no temporary file left
    empty = tmp_path / "empty.png"
    plot_pr(_result(pr_scores=np.zeros(0), pr_recall=np.zeros(0), pr_precision=np.zeros(0), tp=0, fp=0), empty)
    assert cv2.imread(str(empty)).shape == (560, 720, 3)


def test_plot_pr_to_a_folder_that_is_not_there_is_one_error(tmp_path):
    with pytest.raises(FastdetError):
        plot_pr(_result(), tmp_path / "nope" / "pr.png")

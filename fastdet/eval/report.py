"""Formatting an evaluation: the metrics table and the precision-recall plot (PNG)."""
from __future__ import annotations

import math
import os

import cv2
import numpy as np

from ..errors import FastdetError
from ..io.atomic import write_bytes
from .metrics import EvalResult, precision_envelope


def _num(x: float | None, digits: int = 4) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{x:.{digits}f}"


def format_table(result: EvalResult) -> str:
    """A small human-readable table of the result (no trailing newline)."""
    r = result
    rows: list[tuple[str, str]] = [
        ("IoU threshold", f"{r.iou_threshold:g}"),
        ("frames", f"{r.frames} keyframes" if r.keyframes else str(r.frames)),
        ("GT boxes", f"{r.num_gt}  (+ {r.num_ignore} ignore regions)"),
        ("predictions", f"{r.num_pred}  ({r.num_dropped} dropped on ignore regions)"),
        ("TP", str(r.tp)),
        ("FP", str(r.fp)),
        ("FN", str(r.fn)),
        ("precision", _num(r.precision)),
        ("recall", _num(r.recall)),
        ("F1", _num(r.f1)),
        ("FP per frame", _num(r.fp_per_frame, 3)),
        ("AP", _num(r.ap)),
    ]
    if r.has_tracking:
        rows += [
            ("MOTA", _num(r.mota)),
            ("MOTP (1 - IoU)", _num(r.motp)),
            ("IDF1", _num(r.idf1)),
            ("ID switches", str(r.id_switches)),
            ("fragmentations", str(r.fragmentations)),
            ("HOTA", _num(r.hota)),
            ("DetA", _num(r.deta)),
            ("AssA", _num(r.assa)),
        ]
    width = max(len(k) for k, _ in rows)
    lines = [f"{k:<{width}}  {v}" for k, v in rows]
    if r.num_outside and r.keyframes:
        lines.append(f"({r.num_outside} predictions on frames that are not keyframes were not evaluated)")
    elif r.num_outside:
        lines.append(f"({r.num_outside} predictions after the last GT frame {r.frames} were not evaluated)")
    return "\n".join(lines)


def _pr_image(result: EvalResult, title: str | None = None) -> np.ndarray:
    W, H = 720, 560
    left, right, top, bottom = 90, 30, 60, 75
    pw, ph = W - left - right, H - top - bottom
    img = np.full((H, W, 3), 255, np.uint8)
    font = cv2.FONT_HERSHEY_SIMPLEX
    black, grey, blue, light = (0, 0, 0), (225, 225, 225), (180, 90, 20), (235, 190, 150)

    def px(r: float, p: float) -> tuple[int, int]:
        return int(round(left + r * pw)), int(round(top + (1.0 - p) * ph))

    def text_centered(s: str, cx: int, y: int, scale: float, thick: int = 1) -> None:
        (tw, _), _ = cv2.getTextSize(s, font, scale, thick)
        cv2.putText(img, s, (int(cx - tw / 2), y), font, scale, black, thick, cv2.LINE_AA)

    for k in range(11):  # grid and ticks every 0.1, labels every 0.2
        v = k / 10
        x, _ = px(v, 0)
        _, y = px(0, v)
        cv2.line(img, (x, top), (x, top + ph), grey, 1)
        cv2.line(img, (left, y), (left + pw, y), grey, 1)
        cv2.line(img, (x, top + ph), (x, top + ph + 6), black, 1)
        cv2.line(img, (left - 6, y), (left, y), black, 1)
        if k % 2 == 0:
            text_centered(f"{v:.1f}", x, top + ph + 24, 0.5)
            s = f"{v:.1f}"
            (tw, th), _ = cv2.getTextSize(s, font, 0.5, 1)
            cv2.putText(img, s, (left - 10 - tw, y + th // 2), font, 0.5, black, 1, cv2.LINE_AA)
    cv2.rectangle(img, (left, top), (left + pw, top + ph), black, 1)
    text_centered("recall", left + pw // 2, H - 22, 0.65)
    # rotated y label
    (tw, th), base = cv2.getTextSize("precision", font, 0.65, 1)
    lab = np.full((th + base + 4, tw + 4, 3), 255, np.uint8)
    cv2.putText(lab, "precision", (2, th + 2), font, 0.65, black, 1, cv2.LINE_AA)
    lab = cv2.rotate(lab, cv2.ROTATE_90_COUNTERCLOCKWISE)
    y0 = top + ph // 2 - lab.shape[0] // 2
    img[y0:y0 + lab.shape[0], 14:14 + lab.shape[1]] = lab

    if title is None:
        title = f"Precision-recall, IoU >= {result.iou_threshold:g}:  AP = {_num(result.ap, 3)}"
    text_centered(title, W // 2, 36, 0.65, 2)

    rec, prec = result.pr_recall, result.pr_precision
    if rec.size and np.all(np.isfinite(rec)):
        raw = np.array([px(r, p) for r, p in zip(rec, prec)], np.int32)
        cv2.polylines(img, [raw.reshape(-1, 1, 2)], False, light, 1, cv2.LINE_AA)
        env = precision_envelope(prec)
        pts = [px(0.0, env[0])]
        prev = 0.0
        for r, p in zip(rec, env):
            pts.append(px(prev, p))
            pts.append(px(r, p))
            prev = r
        pts.append(px(prev, 0.0))
        cv2.polylines(img, [np.array(pts, np.int32).reshape(-1, 1, 2)], False, blue, 2, cv2.LINE_AA)
        # legend
        lx, ly = left + pw - 230, top + 20
        cv2.line(img, (lx, ly), (lx + 30, ly), blue, 2, cv2.LINE_AA)
        cv2.putText(img, "interpolated (AP area)", (lx + 38, ly + 5), font, 0.45, black, 1, cv2.LINE_AA)
        cv2.line(img, (lx, ly + 20), (lx + 30, ly + 20), light, 1, cv2.LINE_AA)
        cv2.putText(img, "raw", (lx + 38, ly + 25), font, 0.45, black, 1, cv2.LINE_AA)
    else:
        text_centered("no predictions" if rec.size == 0 else "no ground-truth targets",
                      left + pw // 2, top + ph // 2, 0.7)
    return img


def plot_pr(result: EvalResult, path: str | os.PathLike[str], title: str | None = None) -> None:
    """Write the PR curve as a PNG (to a temporary name beside ``path``, then renamed)."""
    path = os.fspath(path)
    ok, buf = cv2.imencode(".png", _pr_image(result, title))
    if not ok:  # pragma: no cover
        raise FastdetError(f"{path}: PNG encoding failed")
    write_bytes(path, buf.tobytes())

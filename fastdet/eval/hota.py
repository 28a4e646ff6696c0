"""HOTA: Higher Order Tracking Accuracy (Luiten et al., "HOTA: A Higher Order Metric for
Evaluating Multi-Object Tracking", IJCV 2021), with its detection (DetA) and association
(AssA) parts.

Written here because the maintained implementations do not install cleanly beside our
pins: TrackEval's PyPI package (``trackeval``) and roboflow's ``trackers`` both require
``opencv-python``, a second ``cv2`` over ``opencv-python-headless``. This follows TrackEval's
``HOTA`` metric (``trackeval/metrics/hota.py``) step by step:

For each localisation threshold ``alpha`` in ``0.05, 0.10, ..., 0.95``:

1. A global alignment score between every ground-truth id ``g`` and predicted id ``p``:
   ``A(g, p) = M(g, p) / (n_g + n_p - M(g, p))``, where ``n_g``, ``n_p`` are the numbers of
   frames the ids appear in and ``M(g, p)`` sums, over frames, the pair's similarity
   normalised as ``S / (row sum + column sum - S)`` (a soft count of matches).
2. Each frame: the Hungarian method maximises ``A(g, p) x IoU(g, p)``; matched pairs with
   ``IoU >= alpha`` are true positives (TP), the other targets false negatives (FN), the
   other predictions false positives (FP). ``c(g, p)`` counts the TP frames of each pair.
3. ``DetA = TP / (TP + FN + FP)``;
   ``AssA = (1 / TP) sum_{TP pairs} c / (n_g + n_p - c)`` (each TP weighted by its pair's
   association Jaccard), ``HOTA_alpha = sqrt(DetA x AssA)``.

The reported ``hota``, ``deta``, ``assa`` are the means over the 19 thresholds (so ``hota``
is not ``sqrt(deta x assa)`` in general). ``loca`` is the mean IoU of the TP pairs, averaged
the same way (1 at a threshold without TPs, as in TrackEval).

Input: per frame, the targets' ids and boxes, the predictions' ids and boxes (predictions
on ignore regions already removed by the caller).
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..boxes import iou

ALPHAS = np.arange(0.05, 0.99, 0.05)  # as TrackEval: 0.05, 0.10, ..., 0.95
_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class HotaResult:
    """HOTA and its parts, each the mean over :data:`ALPHAS` (module docstring).
    ``per_alpha``: ``{'hota', 'deta', 'assa'}`` -> ``(19,)`` arrays."""

    hota: float
    deta: float
    assa: float
    loca: float
    per_alpha: dict


def hota(frames: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]) -> HotaResult:
    """HOTA over ``frames``: each ``(gt_ids (G,), gt_boxes (G, 4), pred_ids (P,), pred_boxes
    (P, 4))`` with boxes ``x1, y1, x2, y2``. Ids are any integers (unique within a frame)."""
    seq = [(np.asarray(gi, np.int64).reshape(-1), np.asarray(gb, np.float64).reshape(-1, 4),
            np.asarray(pi, np.int64).reshape(-1), np.asarray(pb, np.float64).reshape(-1, 4))
           for gi, gb, pi, pb in frames]
    g_ids = np.unique(np.concatenate([f[0] for f in seq])) if seq else np.zeros(0, np.int64)
    p_ids = np.unique(np.concatenate([f[2] for f in seq])) if seq else np.zeros(0, np.int64)
    ng, npr, na = len(g_ids), len(p_ids), len(ALPHAS)
    # dense indices
    frames_idx = [(np.searchsorted(g_ids, gi), gb, np.searchsorted(p_ids, pi), pb) for gi, gb, pi, pb in seq]

    # the id pairs' soft match counts, sparse over the pairs that overlap somewhere (keys
    # g * npr + p): memory follows the overlapping boxes, not n_gt_ids x n_pred_ids
    g_count = np.zeros(ng)
    p_count = np.zeros(npr)
    pot_keys: list[np.ndarray] = []
    pot_vals: list[np.ndarray] = []
    for gi, gb, pi, pb in frames_idx:
        s = iou(gb, pb)
        if s.size:
            denom = s.sum(0)[None, :] + s.sum(1)[:, None] - s
            soft = np.where(denom > _EPS, s / np.where(denom > _EPS, denom, 1.0), 0.0)
            r, c = np.nonzero(soft)
            pot_keys.append(gi[r] * npr + pi[c])
            pot_vals.append(soft[r, c])
        g_count[gi] += 1
        p_count[pi] += 1
    keys, inv = np.unique(np.concatenate(pot_keys) if pot_keys else np.zeros(0, np.int64), return_inverse=True)
    potential = np.bincount(inv.reshape(-1), weights=np.concatenate(pot_vals) if pot_vals else None,
                            minlength=len(keys)).astype(np.float64)

    def align(gi: np.ndarray, pi: np.ndarray) -> np.ndarray:
        """The global alignment score ``A(g, p)`` of a frame's ``(G, P)`` id pairs."""
        k = gi[:, None] * npr + pi[None, :]
        pos = np.minimum(np.searchsorted(keys, k), max(len(keys) - 1, 0))
        found = keys[pos] == k if len(keys) else np.zeros(k.shape, bool)
        pot = np.where(found, potential[pos] if len(keys) else 0.0, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            a = pot / (g_count[gi][:, None] + p_count[pi][None, :] - pot)
        return np.nan_to_num(a)

    tp = np.zeros(na)
    fn = np.zeros(na)
    fp = np.zeros(na)
    loc = np.zeros(na)
    # the TP pairs of each alpha, as keys g * npr + p (sparse: a dense (19, ng, npr) count
    # array is 19 x 8 bytes per id pair, 5.6 GB for 5,000 + 5,000 ids)
    matched: list[list[np.ndarray]] = [[] for _ in range(na)]
    for gi, gb, pi, pb in frames_idx:
        if len(gi) == 0 or len(pi) == 0:
            fn += len(gi)
            fp += len(pi)
            continue
        s = iou(gb, pb)  # again: keeping every frame's matrix would hold them all at once
        r, c = linear_sum_assignment(-(align(gi, pi) * s))
        ms = s[r, c]
        for a, alpha in enumerate(ALPHAS):
            ok = ms >= alpha - _EPS
            n = int(ok.sum())
            tp[a] += n
            fn[a] += len(gi) - n
            fp[a] += len(pi) - n
            loc[a] += ms[ok].sum()
            matched[a].append(gi[r[ok]] * npr + pi[c[ok]])

    assa = np.zeros(na)
    for a in range(na):
        keys, m = np.unique(np.concatenate(matched[a]) if matched[a] else np.zeros(0, np.int64),
                            return_counts=True)
        m = m.astype(np.float64)
        jac = m / np.maximum(1.0, g_count[keys // max(npr, 1)] + p_count[keys % max(npr, 1)] - m)
        assa[a] = (m * jac).sum() / max(1.0, tp[a])
    deta = tp / np.maximum(1.0, tp + fn + fp)
    h = np.sqrt(deta * assa)
    loca = np.maximum(1e-10, loc) / np.maximum(1e-10, tp)
    return HotaResult(float(h.mean()), float(deta.mean()), float(assa.mean()), float(loca.mean()),
                      {"hota": h, "deta": deta, "assa": assa})

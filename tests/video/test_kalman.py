"""The batched Kalman filter of the tracker (fastdet.video.kalman) against the textbook
equations one track at a time, and its box conversions."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.video.kalman import BoxKalman, cxcywh_to_xyxy, xyxy_to_cxcywh


def kalman_reference(z_seq: list[np.ndarray | None], p: float, v: float, v0: float) -> list[np.ndarray]:
    """The textbook constant-velocity Kalman filter of one track, explicit matrices: the mean
    after each frame (``None``: no measurement, predict only)."""
    F = np.eye(8)
    for i in range(4):
        F[i, i + 4] = 1.0
    H = np.zeros((4, 8))
    H[:4, :4] = np.eye(4)
    z0 = z_seq[0]
    x = np.concatenate([z0, np.zeros(4)])
    w, h = z0[2], z0[3]
    P = np.diag(np.array([2 * p * w, 2 * p * h, 2 * p * w, 2 * p * h, v0 * w, v0 * h, v0 * w, v0 * h]) ** 2)
    out = [x.copy()]
    for z in z_seq[1:]:
        w, h = max(x[2], 1.0), max(x[3], 1.0)
        Q = np.diag(np.array([p * w, p * h, p * w, p * h, v * w, v * h, v * w, v * h]) ** 2)
        x = F @ x
        P = F @ P @ F.T + Q
        if z is not None:
            w, h = max(x[2], 1.0), max(x[3], 1.0)
            R = np.diag(np.array([p * w, p * h, p * w, p * h]) ** 2)
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            x = x + K @ (z - H @ x)
            P = P - K @ S @ K.T
        out.append(x.copy())
    return out


def test_batched_kalman_matches_the_textbook_filter_per_track():
    rng = np.random.default_rng(3)
    kf = BoxKalman(1 / 20, 1 / 160, 0.25)
    n, T = 4, 12
    truth = [np.array([100 + 50 * i, 200, 40 + 10 * i, 20 + 5 * i], float) for i in range(n)]
    vel = [np.array([rng.uniform(-15, 15), rng.uniform(-3, 3), 0.5, 0.2]) for _ in range(n)]
    seen = rng.random((T, n)) < 0.75  # which track has a measurement in which frame
    seen[0] = True
    zs = [[truth[i] + t * vel[i] + rng.normal(0, 1, 4) for t in range(T)] for i in range(n)]
    mean, cov = kf.initiate(np.stack([zs[i][0] for i in range(n)]))
    got = [mean.copy()]
    for t in range(1, T):
        mean, cov = kf.predict(mean, cov)
        rows = np.flatnonzero(seen[t])
        if len(rows):
            mean[rows], cov[rows] = kf.update(mean[rows], cov[rows], np.stack([zs[i][t] for i in rows]))
        got.append(mean.copy())
    for i in range(n):
        ref = kalman_reference([zs[i][0]] + [zs[i][t] if seen[t, i] else None for t in range(1, T)],
                               1 / 20, 1 / 160, 0.25)
        np.testing.assert_allclose(np.stack([g[i] for g in got]), np.stack(ref), rtol=1e-9, atol=1e-9)


def test_kalman_learns_a_constant_velocity():
    kf = BoxKalman(1 / 20, 1 / 160, 0.25)
    mean, cov = kf.initiate(np.array([[100.0, 50, 40, 20]]))
    for t in range(1, 15):
        mean, cov = kf.predict(mean, cov)
        mean, cov = kf.update(mean, cov, np.array([[100.0 + 12 * t, 50, 40, 20]]))
    assert mean[0, 4] == pytest.approx(12.0, abs=0.2)
    pred, _ = kf.predict(mean, cov)
    assert pred[0, 0] == pytest.approx(100 + 12 * 15, abs=1.0)


def test_box_conversions_round_trip():
    b = np.array([[10.0, 20, 50, 40], [0, 0, 1, 3]])
    np.testing.assert_allclose(xyxy_to_cxcywh(b), [[30, 30, 40, 20], [0.5, 1.5, 1, 3]])
    np.testing.assert_allclose(cxcywh_to_xyxy(xyxy_to_cxcywh(b)), b)
    assert cxcywh_to_xyxy(np.zeros((0, 8))).shape == (0, 4)

"""Constant-velocity Kalman filter of boxes, batched over tracks (numpy only).

State of a track: ``(cx, cy, w, h, vcx, vcy, vw, vh)`` -- box centre, width, height in
frame pixels and their velocities in pixels per frame. A measurement is a box
``(cx, cy, w, h)``. This is the filter of DeepSORT (Wojke et al., ICIP 2017) as used by
ByteTrack (Zhang et al., ECCV 2022), with the width instead of the aspect ratio in the
state as in BoT-SORT (Aharon et al., 2022): every noise standard deviation is a fraction
of the box's own width or height, so a car far away (small box) and a car close by (large
box) are followed with the same relative uncertainty.

All functions work on stacks: ``mean (N, 8)``, ``cov (N, 8, 8)``, ``z (N, 4)``, and return
new arrays. Noise weights come from :class:`~fastdet.config.TrackerConfig`
(``std_position``, ``std_velocity``, ``init_velocity``).
"""
from __future__ import annotations

import numpy as np

_F = np.eye(8)
_F[:4, 4:] = np.eye(4)  # x_{t+1} = x_t + v_t (one frame); the measurement is the first 4 entries


def xyxy_to_cxcywh(boxes: np.ndarray) -> np.ndarray:
    """``(N, 4)`` x1, y1, x2, y2 -> ``(N, 4) float64`` centre x, centre y, width, height."""
    b = np.asarray(boxes, np.float64).reshape(-1, 4)
    return np.stack([(b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2, b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]], 1)


def cxcywh_to_xyxy(z: np.ndarray) -> np.ndarray:
    """``(N, >=4)`` centre x, centre y, width, height (further columns ignored) -> ``(N, 4)
    float64`` x1, y1, x2, y2."""
    z = np.asarray(z, np.float64)
    z = z.reshape(-1, 4) if z.size == 0 else z.reshape(len(z), -1)
    hw, hh = z[:, 2] / 2, z[:, 3] / 2
    return np.stack([z[:, 0] - hw, z[:, 1] - hh, z[:, 0] + hw, z[:, 1] + hh], 1)


def _size_std(wh: np.ndarray, weight: float) -> np.ndarray:
    """``(N, 4)``: ``weight x (w, h, w, h)`` of each box (``wh (N, 2)``)."""
    return weight * np.concatenate([wh, wh], 1)


class BoxKalman:
    """The filter (module docstring): ``initiate``, ``predict``, ``update`` on stacks of tracks.

    std_position: position noise per frame as a fraction of the box's width / height
        (measurement noise and process noise of the position).
    std_velocity: process noise of the velocity per frame, same units.
    init_velocity: standard deviation of a new track's (unknown, zero) velocity, same units.
    """

    def __init__(self, std_position: float = 1 / 20, std_velocity: float = 1 / 160,
                 init_velocity: float = 10 / 160) -> None:
        self.std_position = float(std_position)
        self.std_velocity = float(std_velocity)
        self.init_velocity = float(init_velocity)

    def initiate(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """New tracks at measurements ``z (N, 4)`` (cx, cy, w, h), velocity 0:
        ``(mean (N, 8), cov (N, 8, 8))``."""
        z = np.asarray(z, np.float64).reshape(-1, 4)
        mean = np.concatenate([z, np.zeros_like(z)], 1)
        std = np.concatenate([_size_std(z[:, 2:], 2 * self.std_position),
                              _size_std(z[:, 2:], self.init_velocity)], 1)
        cov = np.zeros((len(z), 8, 8))
        idx = np.arange(8)
        cov[:, idx, idx] = std ** 2
        return mean, cov

    def predict(self, mean: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One frame ahead: ``mean' = F mean``, ``cov' = F cov F^T + Q`` with ``Q`` from the
        boxes' current sizes."""
        if len(mean) == 0:
            return mean.copy(), cov.copy()
        wh = np.maximum(mean[:, 2:4], 1.0)
        std = np.concatenate([_size_std(wh, self.std_position), _size_std(wh, self.std_velocity)], 1)
        new_mean = mean @ _F.T
        new_cov = _F @ cov @ _F.T
        idx = np.arange(8)
        new_cov[:, idx, idx] += std ** 2
        return new_mean, new_cov

    def update(self, mean: np.ndarray, cov: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Correct tracks ``(mean, cov)`` with their measurements ``z (N, 4)`` (row i of ``z``
        belongs to track i)."""
        z = np.asarray(z, np.float64).reshape(-1, 4)
        if len(z) == 0:
            return mean.copy(), cov.copy()
        wh = np.maximum(mean[:, 2:4], 1.0)
        r = _size_std(wh, self.std_position) ** 2
        s = cov[:, :4, :4].copy()  # H cov H^T
        idx = np.arange(4)
        s[:, idx, idx] += r
        pht = cov[:, :, :4]  # cov H^T, (N, 8, 4)
        gain = np.linalg.solve(s, pht.transpose(0, 2, 1)).transpose(0, 2, 1)  # (N, 8, 4); S symmetric
        innov = z - mean[:, :4]
        new_mean = mean + np.einsum("nij,nj->ni", gain, innov)
        new_cov = cov - gain @ s @ gain.transpose(0, 2, 1)
        return new_mean, new_cov

"""The classic HOG-sub-sampling vehicle pipeline, written plainly: the reference that
fastdet's fast paths are measured and tested against.

Per band: crop, ``cv2.resize`` by ``1/scale``, colour-convert, ``skimage.feature.hog`` of each
channel of the whole scaled band (``feature_vector=False``); then for every window position
one at a time: slice its 7x7 blocks, compute its spatial bins (``cv2.resize``) and colour
histograms (``np.histogram``) from its own pixels, ``StandardScaler.transform`` and
``decision_function`` of a scikit-learn classifier. Nothing here is vectorised across
windows, on purpose.
"""
from __future__ import annotations

import cv2
import numpy as np
from skimage.feature import hog as sk_hog
from sklearn.preprocessing import StandardScaler
from sklearn.svm import LinearSVC

from fastdet.config import FeatureConfig, SearchConfig
from fastdet.detections import Detections
from fastdet.features import convert_color
from fastdet.model import Model
from fastdet.search import BandGeometry, band_geometry, scaled_band, window_boxes


def sklearn_pair(model: Model) -> tuple[StandardScaler, LinearSVC]:
    """A fitted-looking scikit-learn scaler and linear classifier holding ``model``'s numbers."""
    n = model.config.n_features
    scaler = StandardScaler()
    scaler.mean_, scaler.scale_, scaler.var_ = model.mean, model.scale, model.scale ** 2
    scaler.n_features_in_, scaler.n_samples_seen_ = n, 1
    clf = LinearSVC()
    clf.coef_ = model.coef[None, :].copy()
    clf.intercept_ = np.array([model.intercept])
    clf.classes_ = np.array([0, 1])
    clf.n_features_in_ = n
    return scaler, clf


def crop_features(crop_bgr: np.ndarray, config: FeatureConfig) -> np.ndarray:
    """The feature vector of one 64x64 BGR crop, the plain way (HOG of the crop itself)."""
    img = convert_color(crop_bgr, config.color_space)
    hog = np.concatenate([_hog(img[:, :, c], config, True) for c in config.hog_channels])
    return np.concatenate([hog, _color_features(img, config)])


def _hog(channel: np.ndarray, config: FeatureConfig, vector: bool) -> np.ndarray:
    p, c = config.pixels_per_cell, config.cells_per_block
    return sk_hog(channel, orientations=config.orientations, pixels_per_cell=(p, p), cells_per_block=(c, c),
                  block_norm="L2-Hys", transform_sqrt=False, feature_vector=vector)


def _color_features(window: np.ndarray, config: FeatureConfig) -> np.ndarray:
    parts = []
    if config.spatial_size:
        sh, sw = config.spatial_shape
        parts.append(cv2.resize(window, (sw, sh), interpolation=cv2.INTER_LINEAR).ravel().astype(np.float64))
    if config.hist_bins:
        parts += [np.histogram(window[:, :, c], bins=config.hist_bins, range=(0, 256))[0].astype(np.float64)
                  for c in range(3)]
    return np.concatenate(parts) if parts else np.zeros(0)


def band_window_features(frame: np.ndarray, geo: BandGeometry, config: FeatureConfig):
    """Yield ``(row, col, features)`` for every window of the band, one window at a time."""
    img = convert_color(scaled_band(frame, geo), config.color_space)
    hogs = [_hog(img[:, :, c], config, False) for c in config.hog_channels]
    bx, by, cell = config.blocks_x, config.blocks_y, config.pixels_per_cell
    for i in range(geo.ny):
        for j in range(geo.nx):
            yb, xb = i * geo.step, j * geo.step
            hog = np.concatenate([h[yb: yb + by, xb: xb + bx].ravel() for h in hogs])
            y, x = yb * cell, xb * cell
            window = img[y: y + config.win_h, x: x + config.win_w]
            yield i, j, np.concatenate([hog, _color_features(window, config)])


def classic_band_scores(frame: np.ndarray, geo: BandGeometry, model: Model, pair=None) -> np.ndarray:
    """Decision value of every window of one band, one window at a time: ``(ny, nx)``."""
    scaler, clf = pair or sklearn_pair(model)
    out = np.empty((geo.ny, geo.nx))
    for i, j, feat in band_window_features(frame, geo, model.config):
        out[i, j] = clf.decision_function(scaler.transform(feat[None]))[0]
    return out


class ClassicDetector:
    """The classic pipeline with fastdet's ``Detector.detect`` interface (decision values as scores)."""

    def __init__(self, model: Model, search: SearchConfig | None = None):
        self.model, self.search = model, search or SearchConfig()
        self.pair = sklearn_pair(model)

    def detect(self, frame: np.ndarray) -> Detections:
        boxes, scores = [], []
        for band in self.search.bands:
            geo = band_geometry(band, frame.shape[:2], self.model.config, self.search.cells_per_step)
            dec = classic_band_scores(frame, geo, self.model, self.pair)
            r, c = np.nonzero(dec > self.search.threshold)
            boxes.append(window_boxes(geo, r, c, self.model.config))
            scores.append(dec[r, c].astype(np.float32))
        return Detections(np.concatenate(boxes), np.concatenate(scores))

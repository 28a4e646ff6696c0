"""fastdet.train.verifier: labels of the first stage's boxes, the cascade's operating point,
the fit, and the candidates file."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.detect.verifier import VERIFIER_CONTEXTS, VERIFIER_FEATURES
from fastdet.detections import Detections
from fastdet.errors import DataError
from fastdet.labels.picture import AnnotatedPicture
from fastdet.train.verifier import (
    Candidates,
    VerifierRecipe,
    collect,
    fit_verifier,
    label_boxes,
    load_candidates,
    operating_point,
    save_candidates,
)

N_IN = len(VERIFIER_CONTEXTS) * VERIFIER_FEATURES.n_features + 1


def test_labels():
    targets = np.array([[0, 0, 100, 100]], float)
    ignores = np.array([[200, 0, 300, 100]], float)
    boxes = np.array([[0, 0, 100, 100],     # the vehicle: 1
                      [10, 10, 110, 110],   # IoU 0.68: 1
                      [50, 0, 150, 100],    # IoU 0.33: between, left out
                      [400, 0, 500, 100],   # nothing: 0
                      [210, 0, 290, 100],   # inside an ignore region: left out
                      [280, 0, 380, 100]],  # 20% in the ignore region: 0
                     float)
    assert label_boxes(boxes, targets, ignores).tolist() == [1, 1, -1, 0, -1, 0]
    # a partial picture: positives only
    assert label_boxes(boxes, targets, ignores, complete=False).tolist() == [1, 1, -1, -1, -1, -1]
    assert label_boxes(boxes, np.zeros((0, 4)), np.zeros((0, 4))).tolist() == [0] * 6
    assert label_boxes(np.zeros((0, 4)), targets, ignores).tolist() == []


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-20, 20, allow_nan=False), min_size=1, max_size=60),
       st.lists(st.floats(-20, 20, allow_nan=False), max_size=60), st.floats(0.05, 1.0))
def test_operating_point_keeps_the_share_and_is_the_largest(pos, neg, keep):
    values = np.array(pos + neg)
    y = np.array([1] * len(pos) + [0] * len(neg))
    t = operating_point(values, y, keep)
    p = np.array(pos)
    assert (p > t).mean() >= keep - 1e-12
    # the next larger threshold (at the lowest positive kept) keeps less than the share
    assert (p > p[p > t].min()).mean() < keep


def test_operating_point_without_positives():
    with pytest.raises(DataError, match="no first-stage box matches"):
        operating_point(np.zeros(3), np.zeros(3, int), 0.9)


def _candidates(cameras=6, per=30, seed=0, shift=2.0):
    """Synthetic inputs: positives shifted along the first 20 features."""
    rng = np.random.default_rng(seed)
    n = cameras * per
    y = np.tile(np.array([1] * (per // 3) + [0] * (per - per // 3) ), cameras).astype(np.int8)
    x = rng.normal(size=(n, N_IN)).astype(np.float32)
    x[y == 1, :20] += shift
    cams = np.repeat([f"cam{i}" for i in range(cameras)], per)
    return Candidates(x, y, cams, np.arange(n) // 10)


def test_fit_separates_and_keeps_the_share_on_held_out_cameras():
    c = _candidates()
    recipe = VerifierRecipe(C=0.1, folds=3, keep_fraction=0.8)
    v, report = fit_verifier(c, recipe, {"command": "test"})
    assert report["cameras"] == 6 and report["positives"] == 60 and report["threshold"] == v.threshold
    assert report["held_out_positives_kept"] >= 0.8
    assert report["held_out_negatives_passed"] < 0.3
    assert v.metadata["command"] == "test" and v.metadata["training"]["recipe"]["keep_fraction"] == 0.8
    # the fitted verifier on the standardised inputs is sklearn's logistic regression on them
    from sklearn.linear_model import LogisticRegression

    x = c.x.astype(np.float64)
    z = (x - v.mean) / v.scale
    ref = LogisticRegression(C=0.1, class_weight="balanced", max_iter=500).fit(z, c.y)
    np.testing.assert_allclose(z @ v.coef + v.intercept, ref.decision_function(z), atol=1e-3)
    # appearance only: one input fewer
    v2, _ = fit_verifier(c, VerifierRecipe(C=0.1, folds=2, score_input=False))
    assert v2.n_features == N_IN - 1 and not v2.score_input


def test_fit_refuses_too_few_cameras_or_one_class():
    with pytest.raises(DataError, match="needs at least 5"):
        fit_verifier(_candidates(cameras=3))
    c = _candidates()
    with pytest.raises(DataError, match="no positives or no negatives"):
        fit_verifier(Candidates(c.x, np.zeros_like(c.y), c.camera, c.picture))


def test_negatives_are_thinned_per_camera():
    c = _candidates(per=45)
    _, report = fit_verifier(c, VerifierRecipe(max_negatives=10, folds=3))
    assert report["fitted_rows"] == 6 * (15 + 10)


def test_candidates_file(tmp_path):
    c = _candidates()
    key = {"first_stage": {"nms_min_score": 0.0}, "pictures": ["a:1", "b:2"]}
    save_candidates(tmp_path / "c.npz", c, key)
    d = load_candidates(tmp_path / "c.npz", key)
    assert d is not None and d.camera.tolist() == c.camera.tolist() and d.y.dtype == np.int8
    np.testing.assert_array_equal(d.x, c.x)
    assert load_candidates(tmp_path / "c.npz", {**key, "pictures": ["a:1"]}) is None
    assert load_candidates(tmp_path / "none.npz", key) is None
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    assert load_candidates(tmp_path / "junk.npz", key) is None


def test_collect_labels_each_pictures_boxes(tmp_path):
    import cv2

    img = np.zeros((120, 160, 3), np.uint8)
    img[20:60, 20:80] = 200
    paths = []
    for i in range(2):
        p = tmp_path / f"p{i}.png"
        cv2.imwrite(str(p), img)
        paths.append(p)
    pics = [AnnotatedPicture("s", f"cam{i}", p.name, p, 160, 120, targets=np.array([[20, 20, 80, 60]], float))
            for i, p in enumerate(paths)]

    def first_stage(image):
        return Detections(np.array([[20, 20, 80, 60], [100, 70, 150, 110]], np.int32), np.array([3.0, 1.0], np.float32))

    ticks = []
    c = collect(pics, first_stage, tick=lambda: ticks.append(1))
    assert len(c) == 4 and c.y.tolist() == [1, 0, 1, 0] and c.camera.tolist() == ["cam0", "cam0", "cam1", "cam1"]
    assert c.picture.tolist() == [0, 0, 1, 1] and len(ticks) == 2
    assert c.x.shape == (4, N_IN) and c.x[:, -1].tolist() == [3.0, 1.0, 3.0, 1.0]


def test_a_cache_bigger_than_a_model_file_reads_back(tmp_path, monkeypatch):
    """A full-size first-stage cache (1.65 GB of features) is past a model file's array budget:
    with that budget small, a cache past it still loads (it was written, then never read)."""
    import fastdet.model

    c = _candidates()
    key = {"pictures": ["a:1"]}
    save_candidates(tmp_path / "c.npz", c, key)
    monkeypatch.setattr(fastdet.model, "MAX_ARRAY_BYTES", c.x.nbytes // 2)
    with pytest.raises(fastdet.model.ModelError, match="may hold"):
        fastdet.model.read_npz(tmp_path / "c.npz", ("x", "metadata"), "candidates file", 1)
    d = load_candidates(tmp_path / "c.npz", key)
    assert d is not None and np.array_equal(d.x, c.x)

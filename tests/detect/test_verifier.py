"""fastdet.detect.verifier: the box verifier's inputs, decision values and file."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from fastdet.config.models import VERIFIER_MODEL_PATH
from fastdet.detect.regressor import box_features
from fastdet.detect.verifier import VERIFIER_CONTEXTS, VERIFIER_FEATURES, BoxVerifier, load_verifier, verifier_inputs
from fastdet.errors import ModelError
from fastdet.model import read_npz, write_npz

N_APP = len(VERIFIER_CONTEXTS) * VERIFIER_FEATURES.n_features


def _verifier(score_input=True, seed=0, threshold=0.5):
    rng = np.random.default_rng(seed)
    n = N_APP + int(score_input)
    return BoxVerifier(VERIFIER_FEATURES, VERIFIER_CONTEXTS, score_input, rng.normal(size=n), 0.25,
                       rng.normal(size=n), rng.uniform(0.5, 2, size=n), threshold, {"note": "test"})


@pytest.fixture(scope="module")
def frame(test_images):
    return cv2.imread(str(test_images[0]))


BOXES = np.array([[800, 400, 950, 500], [0, 0, 40, 30], [1200, 650, 1280, 720]], np.float64)


def test_inputs_are_the_regressors_features_then_the_score(frame):
    x = verifier_inputs(frame, BOXES, np.array([1.0, -2.0, 3.5]))
    want = box_features(frame, BOXES, VERIFIER_FEATURES, VERIFIER_CONTEXTS)
    assert x.shape == (3, N_APP + 1)
    np.testing.assert_array_equal(x[:, :-1], want)
    assert x[:, -1].tolist() == [1.0, -2.0, 3.5]
    np.testing.assert_array_equal(verifier_inputs(frame, BOXES, None), want)
    with pytest.raises(ValueError, match="2 scores for 3 boxes"):
        verifier_inputs(frame, BOXES, np.zeros(2))


@pytest.mark.parametrize("score_input", [True, False])
def test_decision_values_are_the_plain_logistic_formula(frame, score_input):
    v = _verifier(score_input)
    s = np.array([0.5, 1.5, 2.5])
    got = v.decision_function(frame, BOXES, s)
    x = box_features(frame, BOXES, VERIFIER_FEATURES, VERIFIER_CONTEXTS)
    if score_input:
        x = np.hstack([x, s[:, None]])
    want = [sum((x[i, j] - v.mean[j]) / v.scale[j] * v.coef[j] for j in range(len(v.coef))) + v.intercept
            for i in range(len(x))]
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)
    assert v.decision_function(frame, np.zeros((0, 4)), np.zeros(0)).shape == (0,)
    if score_input:
        with pytest.raises(ValueError, match="give scores"):
            v.decision_function(frame, BOXES)


def test_file_round_trip(tmp_path, frame):
    v = _verifier()
    v.save(tmp_path / "v.npz")
    w = load_verifier(tmp_path / "v.npz")
    assert (w.threshold, w.intercept, w.score_input, w.contexts) == (v.threshold, v.intercept, True, VERIFIER_CONTEXTS)
    assert w.config == v.config and w.metadata["note"] == "test"
    np.testing.assert_array_equal(w.decision_function(frame, BOXES, np.ones(3)),
                                  v.decision_function(frame, BOXES, np.ones(3)))


def _rewrite(src, dst, change_arrays=None, change_meta=None):
    arrays, meta = read_npz(src, ("coef", "intercept", "mean", "scale", "metadata"), "box verifier")
    arrays.pop("metadata")
    if change_arrays:
        arrays.update(change_arrays)
    if change_meta:
        meta = change_meta(json.loads(json.dumps(meta)))
    write_npz(dst, arrays, meta)
    return dst


@pytest.mark.parametrize("arrays, meta, message", [
    ({"coef": np.zeros(5)}, None, "coef must have shape"),
    ({"scale": np.zeros(N_APP + 1)}, None, "scale must be positive"),
    ({"mean": np.full(N_APP + 1, np.inf)}, None, "not finite"),
    ({"intercept": np.zeros(2)}, None, "intercept must hold one number"),
    (None, lambda m: {**m, "threshold": "high"}, "threshold must be a finite number"),
    (None, lambda m: {**m, "contexts": [0.0, 1.5]}, "contexts"),
    (None, lambda m: {k: v for k, v in m.items() if k != "score_input"}, "bad metadata"),
    (None, lambda m: {**m, "format_version": 7}, "format version"),
])
def test_bad_files_are_one_model_error(tmp_path, arrays, meta, message):
    src = _verifier().save(tmp_path / "good.npz")
    bad = _rewrite(src, tmp_path / "bad.npz", arrays, meta)
    with pytest.raises(ModelError, match=message):
        load_verifier(bad)


def test_the_bundled_verifier_loads_and_says_how_it_was_made():
    v = load_verifier()
    assert VERIFIER_MODEL_PATH.is_file() and v.n_features == N_APP + int(v.score_input)
    t = v.metadata["training"]
    assert v.metadata["command"].startswith("python -m tools.scripts.verifier_model")
    assert t["threshold"] == v.threshold and t["cameras"] >= 5
    assert t["held_out_positives_kept"] >= t["recipe"]["keep_fraction"]

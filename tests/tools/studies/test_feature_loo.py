"""The feature study's pieces: the split refit reproduces ``fastdet train``'s sequence split, the
recipe is read from a model's metadata, and the search cost counts features and HOG channels."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fastdet.config import FeatureConfig
from fastdet.model import Model, load_model
from fastdet.train import fit
from tools.studies.feature_loo import cached_split_scores, cost, split_recipe


def test_split_refit_reproduces_the_recorded_sequence_split(data, tmp_path):
    cfg = FeatureConfig(spatial_size=8, hist_bins=8, orientations=4)
    model, _ = fit.train(data, cfg, split="sequence", seed=1, max_per_folder=6, progress=False,
                         truncate=0.5, reencode=0.25, C=0.05, log=lambda *_: None)
    r = split_recipe(model)
    assert (r["C"], r["seed"], r["truncate"], r["reencode"]) == (0.05, 1, 0.5, 0.25)
    out = cached_split_scores("m", model, tmp_path, data, log=lambda *_: None, max_per_folder=6)
    assert out["scores"].shape == out["labels"].shape and (tmp_path / "m.split.npz").is_file()
    # read back from the cache, still checked against the recorded confusion
    again = cached_split_scores("m", model, tmp_path, data, max_per_folder=6)
    np.testing.assert_array_equal(again["scores"], out["scores"])
    # another recipe's scores do not pass the check
    other = Model(config=model.config, coef=model.coef, intercept=model.intercept, mean=model.mean,
                  scale=model.scale, classifier=model.classifier, metadata={"training": {
                      **model.metadata["training"], "sequence_split": {"confusion": [[0, 99], [99, 0]]}}})
    with pytest.raises(RuntimeError, match="not the recorded"):
        cached_split_scores("m", other, tmp_path, data)


def test_split_recipe_refuses_models_with_extra_crops():
    m = load_model(None)
    t = m.metadata["training"]
    assert split_recipe(m)["C"] == t["C"]
    hard = Model(config=m.config, coef=m.coef, intercept=m.intercept, mean=m.mean, scale=m.scale,
                 classifier=m.classifier, metadata={"training": {**t, "data": {**t["data"], "hard_negatives": 5}}})
    with pytest.raises(ValueError, match="crops alone"):
        split_recipe(hard)


def test_cost_counts_features_and_hog_channels(tmp_path):
    m = load_model(None)
    y_only = replace(m.config, hog_channels=(0,), spatial_size=0, hist_bins=0)
    n = y_only.n_features
    path = tmp_path / "y.npz"
    Model(config=y_only, coef=np.zeros(n), intercept=0.0, mean=np.zeros(n), scale=np.ones(n),
          classifier="logreg", metadata={}).save(path)
    today, small = cost(None), cost(str(path))
    assert today["features"] == m.config.n_features and small["features"] == n
    assert small["windows"] == today["windows"] > 0
    assert small["hog_channel_cells"] * 3 == today["hog_channel_cells"]
    assert small["score_macs"] * m.config.n_features == today["score_macs"] * n
    # the oncoming model's share is the same in both
    assert today["all_score_macs"] - today["score_macs"] == small["all_score_macs"] - small["score_macs"]


def test_least_offset_moves_only_as_far_as_the_count_needs():
    from fastdet.train.blend import rate_offset
    from tools.studies.feature_loo import least_offset

    ref = np.array([4.6, 3.6, -0.3, -0.8, -2.0])  # two above 0
    assert least_offset(ref, ref) == 0.0 and rate_offset(ref, ref) > 1  # the midpoint moves the reference
    more = np.array([6.0, 5.0, 0.08, -0.02, -1.4])  # three above 0: up to the third
    d = least_offset(more, ref)
    assert d == pytest.approx(0.08) and int((more > d).sum()) == 2
    fewer = np.array([-0.5, -0.6, -0.9, -1.0, -3.0])  # none above 0: down to just under the second
    d = least_offset(fewer, ref)
    assert -0.6 - 1e-9 < d < -0.6 and int((fewer > d).sum()) == 2
    # random scores: the count always matches the reference's
    rng = np.random.default_rng(0)
    for _ in range(50):
        s, r = rng.normal(size=200), rng.normal(size=200) - 2
        assert int((s > least_offset(s, r)).sum()) == int((r > 0).sum())

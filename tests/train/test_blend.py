"""Linear models blended and offset: the blend scores every feature vector as the weighted mean of
its parts' decision values, an offset moves every decision value by a constant, and the
rate-matching offset lets through as many windows as the reference."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import FeatureConfig
from fastdet.errors import ModelError
from fastdet.model import Model, load_model
from fastdet.train.blend import blend, offset, rate_offset

SMALL = FeatureConfig(hog_channels=(0,), orientations=9, spatial_size=0, hist_bins=0)


def _model(seed: int, cfg: FeatureConfig = SMALL, classifier: str = "logreg") -> Model:
    rng = np.random.default_rng(seed)
    n = cfg.n_features
    return Model(cfg, rng.normal(size=n), float(rng.normal()), rng.normal(size=n), rng.uniform(0.1, 3, n),
                 classifier, {"training": {"seed": seed}})


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 1000), st.integers(0, 1000), st.floats(0, 1), st.floats(-5, 5))
def test_blend_scores_the_weighted_mean_and_offset_moves_it(sa, sb, m, delta):
    a, b = _model(sa), _model(sb + 1001)
    x = np.random.default_rng(sa + sb).normal(size=(20, SMALL.n_features)) * 3
    c = blend([a, b], [1 - m, m])
    want = (1 - m) * a.decision_from_features(x) + m * b.decision_from_features(x)
    np.testing.assert_allclose(c.decision_from_features(x), want, rtol=1e-9, atol=1e-9)
    assert c.metadata["blend"]["weights"] == pytest.approx([1 - m, m])
    d = offset(c, delta)
    np.testing.assert_allclose(d.decision_from_features(x), want - delta, rtol=1e-9, atol=1e-9)
    assert d.metadata["offset"] == pytest.approx(delta)
    assert offset(d, 1.0).metadata["offset"] == pytest.approx(delta + 1.0)


def test_blend_weights_are_normalised_and_checked():
    a, b = _model(0), _model(1)
    x = np.random.default_rng(2).normal(size=(5, SMALL.n_features))
    np.testing.assert_allclose(blend([a, b], [2, 2]).decision_from_features(x),
                               blend([a, b], [0.5, 0.5]).decision_from_features(x))
    np.testing.assert_allclose(blend([a, b], [1, 0]).decision_from_features(x), a.decision_from_features(x))
    for bad in ([1], [-1, 2], [0, 0], [np.nan, 1]):
        with pytest.raises(ValueError):
            blend([a, b], bad)
    with pytest.raises(ValueError, match="other features"):
        blend([a, _model(3, FeatureConfig(hog_channels=(0,), orientations=8, spatial_size=0, hist_bins=0))], [1, 1])
    with pytest.raises(ValueError, match="other features"):
        blend([a, _model(4, classifier="linearsvc")], [1, 1])
    with pytest.raises(ValueError):
        offset(a, np.inf)


def test_a_blend_saves_and_loads(tmp_path):
    bundled = load_model(None)
    c = blend([bundled, bundled], [0.3, 0.7])
    crops = np.random.default_rng(0).integers(0, 256, (4, 64, 64, 3), dtype=np.uint8)
    np.testing.assert_allclose(c.decision_function(crops), bundled.decision_function(crops), rtol=1e-9, atol=1e-9)
    c.save(tmp_path / "m.npz")
    back = load_model(tmp_path / "m.npz")
    np.testing.assert_allclose(back.decision_function(crops), c.decision_function(crops))
    with pytest.raises(ModelError):
        Model(SMALL, np.ones(SMALL.n_features), 0.0, np.zeros(SMALL.n_features), np.zeros(SMALL.n_features))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-8, 8), min_size=1, max_size=60), st.integers(0, 10_000), st.floats(-2, 2))
def test_rate_offset_matches_the_reference_count(ref, seed, threshold):
    r = np.array(ref)
    s = np.random.default_rng(seed).normal(1.0, 3.0, len(r))  # a model that fires more, on other windows
    delta = rate_offset(s, r, threshold)
    k = int((r > threshold).sum())
    got = int((s - delta > threshold).sum())
    ties = int((s == np.sort(s)[::-1][k - 1]).sum()) if k else 0
    assert got == k or (got < k and ties > 1)
    # the same scores need no offset at the same count: the threshold stays between the same two scores
    d0 = rate_offset(r, r, threshold)
    assert int((r - d0 > threshold).sum()) == k


def test_rate_offset_edges():
    assert rate_offset(np.array([3.0, 1.0, -1.0]), np.array([2.0, 0.5, -3.0])) == pytest.approx(0.0)  # 2 above 0
    assert rate_offset(np.array([5.0, 4.0, 3.0]), np.array([-1.0, -2.0, -3.0])) > 5.0   # nothing may pass
    assert rate_offset(np.array([-5.0, -4.0, -3.0]), np.array([1.0, 2.0, 3.0])) < -5.0  # everything passes
    with pytest.raises(ValueError):
        rate_offset(np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError):
        rate_offset(np.zeros(0), np.zeros(0))
    with pytest.raises(ValueError):
        rate_offset(np.array([np.nan]), np.zeros(1))


def _with_side(seed: int):
    """A main model of SMALL features carrying a side-view component (64x32 windows of them)."""
    from dataclasses import replace

    side = _model(seed + 1, replace(SMALL, window_height=32))
    return replace(_model(seed), side=side)


def test_side_offset_moves_the_side_component_alone_and_inf_drops_it(tmp_path):
    import math

    from fastdet.train.blend import side_offset

    m = _with_side(0)
    xs = np.random.default_rng(1).normal(size=(6, m.side.config.n_features)) * 3
    xm = np.random.default_rng(2).normal(size=(6, SMALL.n_features)) * 3
    for delta in (-1.5, 0.0, 2.0):
        moved = side_offset(m, delta)
        assert moved.side is not None and moved.side.config == m.side.config
        assert moved.side.intercept == pytest.approx(m.side.intercept - delta)
        np.testing.assert_allclose(moved.side.decision_from_features(xs), m.side.decision_from_features(xs) - delta,
                                   rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(moved.side.coef, m.side.coef)
        # the main model as it was
        assert moved.intercept == m.intercept and moved.metadata == m.metadata
        np.testing.assert_array_equal(moved.decision_from_features(xm), m.decision_from_features(xm))
        assert moved.side.metadata["offset"] == pytest.approx(delta)
    assert side_offset(side_offset(m, 1.0), 0.5).side.metadata["offset"] == pytest.approx(1.5)
    dropped = side_offset(m, math.inf)
    assert dropped.side is None and dropped.intercept == m.intercept
    np.testing.assert_array_equal(dropped.coef, m.coef)
    for bad in (math.nan, -math.inf):
        with pytest.raises(ValueError):
            side_offset(m, bad)
    with pytest.raises(ValueError, match="no side-view component"):
        side_offset(_model(0), 1.0)
    with pytest.raises(ValueError, match="no side-view component"):
        side_offset(dropped, math.inf)
    # it survives a file
    back = load_model(side_offset(m, 2.0).save(tmp_path / "m.npz"))
    assert back.side is not None and back.side.intercept == pytest.approx(m.side.intercept - 2.0)


def test_offset_moves_the_main_model_and_keeps_its_side_component():
    m = _with_side(3)
    moved = offset(m, 1.25)
    assert moved.side is m.side
    assert moved.intercept == pytest.approx(m.intercept - 1.25)

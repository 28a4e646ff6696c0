"""Detector(components=...): more whole-vehicle models, each with its own search; their windows
are those the same model gives on its own, tagged with their part."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.config import ONCOMING_SEARCH, SearchBand, SearchConfig
from fastdet.detect import Detector, DetectStats
from fastdet.detections import FIRST_COMPONENT_PART, MAIN_PART, ONCOMING_PART
from fastdet.errors import ModelError
from fastdet.model import ONCOMING_MODEL_PATH, load_model
from tests.reference import classic_band_scores, sklearn_pair


def _sorted(boxes, scores):
    order = np.lexsort((scores, *boxes.T[::-1]))
    return boxes[order], scores[order]


@pytest.fixture(scope="module")
def frame(test_images):
    return cv2.imread(str(test_images[0]))


def test_component_windows_are_the_models_own(frame):
    low = SearchConfig(bands=(SearchBand(1.0, 380, 480), SearchBand(2.0, 380, 560)), threshold=-2.0)
    plain = Detector(oncoming=ONCOMING_MODEL_PATH, oncoming_search=low)
    ref = plain.detect(frame)
    ref_wide = ref[ref.part == ONCOMING_PART]
    assert len(ref_wide) > 10
    both = Detector(oncoming=ONCOMING_MODEL_PATH, oncoming_search=low, components=[(ONCOMING_MODEL_PATH, low),
                                                                          (None, SearchConfig())])
    assert both.parts == [MAIN_PART, ONCOMING_PART, FIRST_COMPONENT_PART, FIRST_COMPONENT_PART + 1]
    assert both.main_parts == [MAIN_PART, FIRST_COMPONENT_PART, FIRST_COMPONENT_PART + 1]
    got = both.detect(frame)
    for part, want in ((FIRST_COMPONENT_PART, ref_wide), (ONCOMING_PART, ref_wide),
                       (MAIN_PART, ref[ref.part == MAIN_PART]),
                       (FIRST_COMPONENT_PART + 1, ref[ref.part == MAIN_PART])):
        mine = got[got.part == part]
        b1, s1 = _sorted(mine.boxes, mine.scores)
        b2, s2 = _sorted(want.boxes, want.scores)
        np.testing.assert_array_equal(b1, b2)
        np.testing.assert_allclose(s1, s2, rtol=1e-6)


def test_columns_cover_the_component_bands_too(frame):
    comp = SearchConfig(bands=(SearchBand(1.5, 380, 520),), threshold=-3.0)
    det = Detector(components=[(ONCOMING_MODEL_PATH, comp)])
    geos = det.main_geometries(frame.shape[:2])
    assert [p for p, _ in geos] == [MAIN_PART] * len(SearchConfig().bands) + [FIRST_COMPONENT_PART]
    full = DetectStats()
    det.detect(frame, stats=full)
    # score only the component band's columns 3..9; every main band's none
    cols = [[(0, 0)]] * (len(geos) - 1) + [[(3, 9)]]
    part = DetectStats()
    out = det.detect(frame, stats=part, columns=cols)
    assert set(out.part.tolist()) <= {FIRST_COMPONENT_PART}
    dec_full, dec_part = full.bands[-1][2], part.bands[-1][2]
    np.testing.assert_allclose(dec_part[:, 3:9], dec_full[:, 3:9], rtol=0, atol=1e-9)
    assert np.isneginf(dec_part[:, :3]).all() and np.isneginf(dec_part[:, 9:]).all()
    with pytest.raises(ValueError, match="entries"):
        det.detect(frame, columns=[None] * (len(geos) + 1))


def test_horizon_moves_every_component_and_kinds_must_agree(frame, tmp_path):
    comp = SearchConfig(bands=(SearchBand(1.5, 380, 520),))
    det = Detector(components=[(ONCOMING_MODEL_PATH, comp)], horizon=0.5)
    y = det.geometries(frame.shape[:2], FIRST_COMPONENT_PART)[0].y0
    det.set_horizon(None)
    assert det.geometries(frame.shape[:2], FIRST_COMPONENT_PART)[0].y0 > y
    m = load_model(ONCOMING_MODEL_PATH)
    svc = type(m)(m.config, m.coef, m.intercept, m.mean, m.scale, classifier="linearsvc")
    with pytest.raises(ModelError, match="component 1"):
        Detector(components=[(svc, ONCOMING_SEARCH)])
    with pytest.raises(TypeError, match="SearchConfig"):
        Detector(components=[(m, "bands")])  # type: ignore[list-item]


# ---- a side-view component the main model carries (Model.side) ----------------------------


def side_model(main, frame, seed=0, positive=0.02):
    """A random wide (64x32) logistic-regression model of ``main``'s features, standardised on
    windows of ``frame`` and with an intercept that lets about ``positive`` of them through."""
    from fastdet.features import extract_features
    from fastdet.model import Model
    from fastdet.train.side import side_config

    cfg = side_config(main.config)
    rng = np.random.default_rng(seed)
    ys = rng.integers(380, frame.shape[0] - 200, 300)
    xs = rng.integers(0, frame.shape[1] - 128, 300)
    hs = rng.choice([24, 32, 48, 64], 300)
    crops = np.stack([cv2.resize(frame[y:y + h, x:x + 2 * h], (cfg.win_w, cfg.win_h)) for y, x, h in zip(ys, xs, hs)])
    x = extract_features(crops, cfg)
    mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-3
    coef = rng.normal(size=cfg.n_features) * 3 / np.sqrt(cfg.n_features)
    dec = ((x - mean) / scale) @ coef
    return Model(cfg, coef, -float(np.quantile(dec, 1 - positive)), mean, scale, classifier=main.classifier,
                 metadata={"note": "random side"})


@pytest.fixture(scope="module")
def carried(frame):
    """The bundled model carrying a random side-view component."""
    from dataclasses import replace

    main = load_model()
    return replace(main, side=side_model(main, frame))


def _bands(det, frame, threads, **kw):
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        stats = DetectStats()
        out = det.detect(frame, stats=stats, **kw)
    finally:
        numba.set_num_threads(before)
    return out, stats.bands


@pytest.mark.parametrize("threads", [1, 2])
def test_a_carried_side_component_scores_each_band_as_its_model_alone(frame, carried, threads, monkeypatch):
    """Detector(model carrying a side-view component): the component is the first component, at
    the main search; each of its bands is scored in one job with the main model's twin band
    (pixels and HOG once), and every decision value is the one each model gives that band on its
    own; the main model's values and windows are those of a Detector without the component."""
    from dataclasses import replace

    from fastdet.detect import band_scorer, detector
    from fastdet.detect.band_scorer import _Scorer, image_key

    jobs = []
    real = detector.group_band_scores

    def spy(frame, members, *a, **kw):
        jobs.append(len(members))
        return real(frame, members, *a, **kw)

    monkeypatch.setattr(detector, "group_band_scores", spy)
    det = Detector(carried)
    assert det.parts == det.main_parts == [MAIN_PART, FIRST_COMPONENT_PART] and det.components == [carried.side]
    got, bands = _bands(det, frame, threads)
    n = len(det.search.bands)
    assert [p for p, _, _ in bands] == [MAIN_PART] * n + [FIRST_COMPONENT_PART] * n
    assert sorted(jobs) == [2] * n  # each side band shares its twin main band's job
    monkeypatch.setattr(detector, "group_band_scores", real)

    plain = Detector(replace(carried, side=None))
    ref_windows, ref_bands = _bands(plain, frame, threads)
    alone = _Scorer(carried.side, det.search)
    for (p, geo, dec), (_, main_geo, main_dec) in zip(bands[n:], bands[:n]):
        assert image_key(geo) == image_key(main_geo) and geo.ny > main_geo.ny
        np.testing.assert_allclose(dec, alone.band_scores(frame, geo, None), rtol=1e-12, atol=1e-9)
    # and, for the two bands of fewest windows, those of each window's features made on their own
    pair = sklearn_pair(carried.side)
    for _, geo, dec in sorted(bands[n:], key=lambda b: b[1].n_windows)[:2]:
        np.testing.assert_allclose(dec, classic_band_scores(frame, geo, carried.side, pair), rtol=0, atol=1e-6)
    for (p, geo, dec), (rp, rgeo, rdec) in zip(bands[:n], ref_bands):
        assert (p, geo) == (rp, rgeo)
        np.testing.assert_allclose(dec, rdec, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(dec, band_scorer._Scorer(carried, det.search).band_scores(frame, geo, None),
                                   rtol=1e-12, atol=1e-9)
    main_w = got[got.part == MAIN_PART]
    np.testing.assert_array_equal(*(_sorted(w.boxes, w.scores)[0] for w in (main_w, ref_windows)))
    # the side windows: those of the reference values at the main search's thresholds, and those
    # of a Detector given the same model as an explicit component at the same search
    side_w = got[got.part == FIRST_COMPONENT_PART]
    assert 5 < len(side_w) < 1000
    inside = (side_w.boxes[:, 0] > 0) & (side_w.boxes[:, 2] < frame.shape[1])  # not clipped at the sides
    w, h = (side_w.boxes[inside, 2:] - side_w.boxes[inside, :2]).T
    assert len(w) and np.all(np.abs(w - 2 * h) <= 2), np.c_[w, h]  # 2:1 windows (to the rounding of corners)
    want = det.windows([(FIRST_COMPONENT_PART, g, alone.band_scores(frame, g, None)) for _, g, _ in bands[n:]])
    explicit, _ = _bands(Detector(replace(carried, side=None), components=[(carried.side, det.search)]), frame,
                         threads)
    for other in (want, explicit[explicit.part == FIRST_COMPONENT_PART]):
        b1, s1 = _sorted(side_w.boxes, side_w.scores)
        b2, s2 = _sorted(other.boxes, other.scores)
        np.testing.assert_array_equal(b1, b2)
        np.testing.assert_allclose(s1, s2, rtol=1e-6)


def test_band_columns_give_the_side_bands_their_twins_columns(frame, carried):
    """Component bands without an entry take the entry of the main band with the same pixels
    (the side-view component's band at the same search band); entries given are kept; bands
    without a twin, or whose twin has no entry, search in full."""
    det = Detector(carried)
    shape = frame.shape[:2]
    geos = det.main_geometries(shape)
    n = len(det.search.bands)
    assert len(geos) == 2 * n
    assert det.band_columns(None, shape) is None
    main_cols = [[(0, 5)], None, [(3, 9), (20, 25)], [], [(1, 2)], [(0, 40)], [(7, 8)]]
    assert len(main_cols) == n
    assert det.band_columns(main_cols, shape) == main_cols + main_cols
    given = main_cols + [[(4, 6)], None]
    assert det.band_columns(given, shape) == given + main_cols[2:]
    assert det.band_columns(main_cols[:3], shape) == main_cols[:3] + [None] * (n - 3) + main_cols[:3] + [None] * (
        n - 3)
    # a component of its own search has no twin among the main bands
    other = Detector(components=[(ONCOMING_MODEL_PATH, SearchConfig(bands=(SearchBand(1.5, 380, 520),)))])
    k = len(other.search.bands)
    assert other.band_columns([[(0, 3)]] * k, shape) == [[(0, 3)]] * k + [None]
    # a component on the main search but of other features (here other orientations: equal
    # band images, another HOG) is no twin either: searched in full
    from dataclasses import replace as dc_replace

    from fastdet.model import Model

    cfg = dc_replace(carried.side.config, orientations=6)
    nf = cfg.n_features
    odd = Model(cfg, np.zeros(nf), 0.0, np.zeros(nf), np.ones(nf), classifier=carried.classifier)
    mixed = Detector(dc_replace(carried, side=None), det.search, components=[(odd, det.search)])
    assert mixed.band_columns(main_cols, shape) == main_cols + [None] * n

    # detect: columns of the main bands only (the side bands take them too), or some side bands' own
    _, full = _bands(det, frame, 2)
    for columns in (main_cols, given):
        got, part = _bands(det, frame, 2, columns=columns)
        assert len(got) and set(got.part.tolist()) <= {MAIN_PART, FIRST_COMPONENT_PART}
        for b, ((p, geo, dec), (_, _, ref), cols) in enumerate(zip(part, full, det.band_columns(columns, shape))):
            want = np.zeros(geo.nx, bool)
            for j0, j1 in cols if cols is not None else [(0, geo.nx)]:
                want[j0:min(j1, geo.nx)] = True
            np.testing.assert_allclose(dec[:, want], ref[:, want], rtol=0, atol=1e-9)
            assert np.all(dec[:, ~want] == -np.inf), (p, b)
            assert p == (MAIN_PART if b < n else FIRST_COMPONENT_PART)
    with pytest.raises(ValueError, match="entries"):
        det.detect(frame, columns=[None] * (2 * n + 1))


def test_side_false_leaves_the_carried_component_out(frame, carried):
    """Detector(side=False): the main model's own windows, as a Detector on the model without
    its component gives them; the components given still join."""
    from dataclasses import replace

    alone = Detector(carried, side=False)
    assert alone.components == [] and alone.parts == [MAIN_PART]
    want = Detector(replace(carried, side=None)).detect(frame)
    got = alone.detect(frame)
    np.testing.assert_array_equal(got.boxes, want.boxes)
    np.testing.assert_array_equal(got.scores, want.scores)
    given = Detector(carried, components=[(carried.side, SearchConfig())], side=False)
    assert given.parts == [MAIN_PART, FIRST_COMPONENT_PART]

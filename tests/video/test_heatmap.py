"""HeatMap against a plain, slow reference (``tests.reference``): a list of the last N
full-frame float arrays, one per frame, summed with their age weights; labels against a
naive flood fill."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fastdet.video.heatmap as heatmap_mod
from fastdet.config import HeatConfig, PipelineConfig
from fastdet.detections import Detections
from fastdet.video.heatmap import HeatMap
from tests.reference import ref_blobs, ref_heat


def as_sorted(d: Detections):
    return sorted((tuple(int(v) for v in b), float(s)) for b, s in zip(d.boxes, d.scores))


# ------------------------------------------------------------------------- strategies


@st.composite
def box_sequences(draw, dyadic: bool):
    h = draw(st.integers(6, 40))
    w = draw(st.integers(6, 40))
    n_frames = draw(st.integers(1, 6))
    cell = draw(st.sampled_from([1, 2, 3, 4]))
    if dyadic:  # every value a short binary fraction: the running sum is exact
        decay = draw(st.sampled_from([1.0, 0.5, 0.25]))
        cfg = HeatConfig(n_frames=n_frames, decay=decay, cell=cell, score_lo=0.0, score_hi=4.0, w_max=5.0,
                         threshold=draw(st.sampled_from([0.0, 1.0, 2.5, 4.0])), min_width=0, min_height=0,
                         max_aspect=100.0, extent=draw(st.sampled_from([0.0, 0.25, 0.5, 1.0])))
        score = st.integers(-1, 6).map(float)
    else:
        decay = draw(st.floats(0.05, 1.0))
        cfg = HeatConfig(n_frames=n_frames, decay=decay, cell=cell, threshold=draw(st.floats(0, 5)),
                         w_max=draw(st.floats(1, 8)), min_width=0, min_height=0, max_aspect=100.0)
        score = st.floats(-3, 5, allow_nan=False)
    coord_x = st.integers(-8, w + 8)
    coord_y = st.integers(-8, h + 8)
    box = st.tuples(coord_x, coord_y, coord_x, coord_y)
    frame = st.lists(st.tuples(box, score), max_size=6)
    frames = draw(st.lists(frame, min_size=1, max_size=14))
    seq = []
    for fr in frames:
        b = np.array([x for x, _ in fr], np.int32).reshape(-1, 4)
        s = np.array([y for _, y in fr], np.float32)
        seq.append((b, s))
    return (h, w), cfg, seq


SETTINGS = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(box_sequences(dyadic=True))
def test_running_sum_equals_reference_exactly(case):
    shape, cfg, seq = case
    hm = HeatMap(shape, cfg)
    for i in range(len(seq)):
        out = hm.update(Detections(*seq[i]))
        ref = ref_heat(seq[: i + 1], shape, cfg)
        assert hm.heat.shape == ref.shape
        np.testing.assert_array_equal(hm.heat, ref)
        np.testing.assert_array_equal(hm.mask, ref > cfg.threshold)
        assert as_sorted(out) == ref_blobs(ref, shape, cfg)


@SETTINGS
@given(box_sequences(dyadic=False))
def test_running_sum_matches_reference_float(case):
    shape, cfg, seq = case
    hm = HeatMap(shape, cfg)
    for i in range(len(seq)):
        hm.update(Detections(*seq[i]))
        np.testing.assert_allclose(hm.heat, ref_heat(seq[: i + 1], shape, cfg), rtol=1e-12, atol=1e-12)


def test_no_drift_over_a_long_run():
    rng = np.random.default_rng(1)
    shape = (48, 64)
    for decay in (1.0, 0.9):
        cfg = HeatConfig(n_frames=5, decay=decay, cell=4)
        hm = HeatMap(shape, cfg)
        seq = []
        for _ in range(700):
            n = rng.integers(0, 6)
            xy = rng.integers(-10, 60, (n, 2))
            wh = rng.integers(1, 40, (n, 2))
            b = np.concatenate([xy, xy + wh], 1).astype(np.int32)
            s = rng.normal(1, 1.5, n).astype(np.float32)
            seq.append((b, s))
            hm.add(b, s)
        np.testing.assert_allclose(hm.heat, ref_heat(seq, shape, cfg), rtol=1e-12, atol=1e-12)


def test_cost_per_frame_does_not_grow_with_n(monkeypatch):
    """One update rasterises the new frame and (once full) the leaving one: two calls of the
    kernel whatever N is; recomputing the sum from scratch happens every max(64, N) frames."""
    calls = []
    real = heatmap_mod.add_rects
    monkeypatch.setattr(heatmap_mod, "add_rects", lambda *a: (calls.append(len(a[1])), real(*a)))
    box = Detections(np.array([[0, 0, 16, 16]], np.int32), np.ones(1, np.float32))
    for n in (2, 50):
        hm = HeatMap((32, 32), HeatConfig(n_frames=n, decay=0.9))
        per_frame = []
        for _ in range(200):
            calls.clear()
            hm.add(box.boxes, box.scores)
            per_frame.append(len(calls))
        spikes = [i for i, k in enumerate(per_frame) if k > 2]
        assert max(k for k in per_frame if k <= 2) == 2
        assert spikes == [i for i in range(200) if (i + 1) % max(64, n) == 0]


# ------------------------------------------------------------------------- score → heat


def test_window_heat_mapping_and_strong_beats_weak():
    cfg = HeatConfig()
    hm = HeatMap((64, 64), cfg)
    lo, hi = cfg.score_range("decision")
    assert (lo, hi) == HeatConfig.SCORE_RANGES["decision"]
    h = hm.window_heat(np.array([lo - 5, lo, (lo + hi) / 2, hi, hi + 10]))
    np.testing.assert_allclose(h, [1, 1, (1 + cfg.w_max) / 2, cfg.w_max, cfg.w_max])
    # one window at score_hi outweighs three barely-positive ones at the same place
    strong = HeatMap((64, 64), cfg)
    strong.add(np.array([[0, 0, 32, 32]]), np.array([hi]))
    weak = HeatMap((64, 64), cfg)
    weak.add(np.array([[0, 0, 32, 32]] * 3), np.array([lo + 0.01] * 3))
    assert strong.heat.max() > weak.heat.max()
    prob = HeatMap((64, 64), cfg, score_kind="probability")
    np.testing.assert_allclose(prob.window_heat([0.5, 0.75, 1.0]), [1, (1 + cfg.w_max) / 2, cfg.w_max])
    custom = HeatMap((64, 64), HeatConfig(score_lo=1.0, score_hi=3.0, w_max=2.0))
    np.testing.assert_allclose(custom.window_heat([0, 2, 5]), [1, 1.5, 2])


def test_grid_snapping():
    hm = HeatMap((30, 41), HeatConfig(cell=4))
    assert hm.grid_shape == (8, 11)
    g = hm.to_grid(np.array([
        [0, 0, 64, 64],      # whole cells, clipped to the grid
        [2, 2, 5, 5],        # halves round up; a non-empty box keeps one cell
        [1, 1, 2, 2],        # rounds to (0, 0, 0, 0) then keeps one cell
        [-30, -30, -20, -20],  # off the frame: empty after clipping
        [10, 10, 10, 20],    # degenerate: stays empty
        [38, 26, 41, 30],    # last partial cell
    ]))
    assert g.tolist() == [[0, 0, 11, 8], [1, 1, 2, 2], [0, 0, 1, 1], [0, 0, 0, 0],
                          [3, 3, 3, 5], [10, 7, 11, 8]]


# ------------------------------------------------------------------------- labels, boxes, filter


def _one_frame(boxes, scores=None, shape=(200, 300), **kw):
    kw.setdefault("cell", 1)
    kw.setdefault("extent", 0.0)
    kw.setdefault("reference_rows", None)  # sizes in pixels of these small frames
    cfg = HeatConfig(n_frames=1, **kw)
    hm = HeatMap(shape, cfg)
    boxes = np.array(boxes, np.int32).reshape(-1, 4)
    scores = np.full(len(boxes), 10.0, np.float32) if scores is None else np.asarray(scores, np.float32)
    return hm, hm.update(Detections(boxes, scores))


def test_separate_and_merged_blobs():
    # two separate vehicles, each seen by two overlapping windows
    hm, out = _one_frame([[10, 10, 74, 74], [18, 10, 82, 74], [150, 20, 214, 84], [158, 28, 222, 92]],
                         threshold=4.0)  # each window 4.0: only overlaps pass
    assert as_sorted(out) == [((18, 10, 74, 74), 8.0), ((158, 28, 214, 84), 8.0)]
    assert hm.labels.max() == 2
    # the same windows at threshold 0: overlapping windows merge into one blob each
    _, out = _one_frame([[10, 10, 74, 74], [18, 10, 82, 74], [150, 20, 214, 84], [158, 28, 222, 92]],
                        threshold=0.0)
    assert [b for b, _ in as_sorted(out)] == [(10, 10, 82, 74), (150, 20, 222, 92)]
    # diagonal touching is not connected (4-connectivity)
    _, out = _one_frame([[0, 0, 50, 50], [50, 50, 100, 100]], threshold=0.0, min_width=0, min_height=0)
    assert len(out.boxes) == 2


def test_box_score_is_peak_heat():
    _, out = _one_frame([[0, 0, 64, 64], [32, 0, 96, 64]], scores=[0.0, 2.0], threshold=0.5)
    assert as_sorted(out) == [((0, 0, 96, 64), 5.0)]  # 1 + 4 where they overlap


def test_extent_box_is_the_core_of_the_blob():
    # heat 4 on x 0..32, 5 on 32..64 (overlap), 1 on 64..96
    boxes = [[0, 0, 64, 64], [32, 0, 96, 64]]
    kw = dict(scores=[2.0, 0.0], threshold=0.5, min_width=0, min_height=0, max_aspect=10.0)
    assert as_sorted(_one_frame(boxes, extent=0.0, **kw)[1]) == [((0, 0, 96, 64), 5.0)]
    assert as_sorted(_one_frame(boxes, extent=0.2, **kw)[1]) == [((0, 0, 96, 64), 5.0)]
    assert as_sorted(_one_frame(boxes, extent=0.5, **kw)[1]) == [((0, 0, 64, 64), 5.0)]
    assert as_sorted(_one_frame(boxes, extent=1.0, **kw)[1]) == [((32, 0, 64, 64), 5.0)]
    # the shape filter sees the core box: 32 px wide is too narrow for min_width 40
    assert len(_one_frame(boxes, extent=1.0, **{**kw, "min_width": 40})[1].boxes) == 0


def test_split_gap_gives_one_box_per_group_of_windows():
    # two cars side by side: windows over x 0..64 and 40..104 on the first, 100..164 and
    # 140..204 on the second; every window overlaps the next, so they make one blob
    boxes = [[0, 0, 64, 24], [40, 0, 104, 24], [100, 0, 164, 24], [140, 0, 204, 24]]
    kw = dict(threshold=0.5, min_width=0, min_height=0, max_aspect=10.0, extent=0.0)
    one = as_sorted(_one_frame(boxes, **kw)[1])
    assert [b for b, _ in one] == [(0, 0, 204, 24)]
    # centres 32, 72, 132, 172: gaps 40, 60, 40 against half a window (32): every gap splits
    two = as_sorted(_one_frame(boxes, split_gap=0.5, **kw)[1])
    assert [b for b, _ in two] == [(0, 0, 64, 24), (40, 0, 104, 24), (100, 0, 164, 24), (140, 0, 204, 24)]
    # against 0.75 of a window (48) only the middle gap: one box per car
    cars = as_sorted(_one_frame(boxes, split_gap=0.75, **kw)[1])
    assert [b for b, _ in cars] == [(0, 0, 104, 24), (100, 0, 204, 24)]
    # windows of one car (centres 8 px apart) stay one box
    same = [[0, 0, 64, 24], [8, 0, 72, 24], [16, 0, 80, 24]]
    assert as_sorted(_one_frame(same, split_gap=0.5, **kw)[1]) == as_sorted(_one_frame(same, **kw)[1])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, 150), st.integers(0, 80), st.integers(8, 80), st.integers(8, 40)),
                min_size=0, max_size=12),
       st.floats(0.0, 1.0))
def test_split_gap_too_large_to_cut_changes_nothing(wins, extent):
    boxes = [[x, y, x + w, y + h] for x, y, w, h in wins]
    kw = dict(threshold=0.5, min_width=0, min_height=0, max_aspect=10.0, extent=extent, shape=(130, 240))
    assert as_sorted(_one_frame(boxes, split_gap=1e6, **kw)[1]) == as_sorted(_one_frame(boxes, **kw)[1])


def test_shape_filter():
    cases = {
        (0, 0, 30, 60): False,    # too narrow (< 40)
        (0, 0, 60, 15): False,    # too low (< 20)
        (0, 0, 40, 61): False,    # taller than 1.5 x width
        (0, 0, 40, 60): True,     # exactly 1.5 x width
        (0, 0, 40, 20): True,     # the smallest kept
        (0, 0, 200, 30): True,    # wide and low (two cars side by side)
    }
    for box, kept in cases.items():
        hm, out = _one_frame([box], threshold=0.0, min_width=40, min_height=20, max_aspect=1.5)
        assert len(hm.blobs.boxes) == 1
        assert (len(out.boxes) == 1) == kept, box


def test_boxes_clipped_to_frame_and_cells():
    hm, out = _one_frame([[250, 150, 400, 260]], shape=(203, 301), cell=4, threshold=0.0)
    assert as_sorted(out) == [((252, 152, 301, 203), 4.0)]


def test_first_frames_normalised_and_reset():
    cfg = HeatConfig(n_frames=4, decay=0.5, cell=1, threshold=0.0)
    hm = HeatMap((50, 50), cfg)
    b = np.array([[0, 0, 10, 10]], np.int32)
    hm.add(b, np.array([10.0]))
    assert hm.heat.max() == cfg.w_max  # one frame seen: its own heat, not diluted by empty frames
    hm.add(np.zeros((0, 4), np.int32), np.zeros(0))
    assert hm.heat.max() == pytest.approx(cfg.w_max * 0.5 / 1.5)
    hm.reset()
    assert hm.n_seen == 0 and hm.heat.max() == 0
    assert len(hm.boxes().boxes) == 0


def test_empty_input_and_bad_arguments():
    hm = HeatMap((10, 10, 3))
    out = hm.update(Detections.empty())
    assert out.boxes.shape == (0, 4) and out.boxes.dtype == np.int32 and out.scores.dtype == np.float32
    with pytest.raises(ValueError):
        hm.add(np.zeros((2, 4)), np.zeros(3))
    with pytest.raises(ValueError):
        HeatMap((0, 10))
    with pytest.raises(ValueError):
        HeatMap((10, 10), score_kind="votes")


# ------------------------------------------------------------------------- label kernel
# The blob labelling kernel (fastdet.video._label_kernels) against scipy.ndimage.label and the
# flood fill of tests.reference; HeatMap's blob boxes against the SciPy-based code it replaced.

from scipy import ndimage  # noqa: E402

from fastdet.video._label_kernels import extent_boxes, label_blobs  # noqa: E402
from tests.reference import flood_components  # noqa: E402


def kernel_label(heat: np.ndarray, thr: float):
    labels = np.full(heat.shape, -7, np.int32)  # garbage in: every cell must be written
    k = heat.size // 2 + 2
    bbox, peak = np.empty((k, 4), np.int64), np.empty(k, np.float64)
    n = label_blobs(np.ascontiguousarray(heat, np.float64), float(thr), labels, bbox, peak)
    return labels, n, bbox[:n], peak[:n]


def check_labels(heat: np.ndarray, thr: float, extent: float = 0.4) -> None:
    labels, n, bbox, peak = kernel_label(heat, thr)
    ref, rn = ndimage.label(heat > thr)
    assert n == rn
    np.testing.assert_array_equal(labels, ref)
    comps = flood_components(heat > thr)  # raster order of each blob's first cell
    assert len(comps) == n
    for i, comp in enumerate(comps):
        ys, xs = zip(*comp)
        assert all(labels[p] == i + 1 for p in comp)
        assert tuple(bbox[i]) == (min(ys), max(ys) + 1, min(xs), max(xs) + 1)
        assert peak[i] == max(heat[p] for p in comp)
    eb = np.empty((n, 4), np.int64)
    extent_boxes(np.ascontiguousarray(heat, np.float64), labels, n, bbox, peak, float(extent), eb)
    for i, comp in enumerate(comps):
        core = [p for p in comp if extent <= 0 or heat[p] >= extent * peak[i]]
        ys, xs = zip(*core)
        assert tuple(eb[i]) == (min(ys), max(ys) + 1, min(xs), max(xs) + 1)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(h=st.integers(1, 24), w=st.integers(1, 24), density=st.floats(0, 1), seed=st.integers(0, 2**31 - 1),
       extent=st.sampled_from([0.0, 0.3, 0.4, 1.0]))
def test_label_kernel_matches_scipy_and_flood_fill(h, w, density, seed, extent):
    rng = np.random.default_rng(seed)
    heat = np.where(rng.random((h, w)) < density, rng.random((h, w)) * 10, 0.0)
    check_labels(heat, 1.0, extent)


@pytest.mark.parametrize("pattern", ["checker", "stripes", "spiral", "full", "empty", "comb"])
def test_label_kernel_worst_shapes(pattern):
    """Shapes that stress union-find: most blobs possible, merges from far right, one blob."""
    h, w = 31, 37
    y, x = np.mgrid[:h, :w]
    mask = {"checker": (y + x) % 2 == 0, "stripes": x % 2 == 0, "full": np.ones((h, w), bool),
            "empty": np.zeros((h, w), bool),
            "comb": (y == h - 1) | (x % 2 == 0),  # teeth joined only on the last row
            "spiral": np.zeros((h, w), bool)}[pattern]
    if pattern == "spiral":
        t, l, b, r = 0, 0, h - 1, w - 1
        while t <= b and l <= r:
            mask[t, l:r + 1] = mask[t:b + 1, r] = True
            mask[b, l:r + 1] = True
            mask[t + 2:b + 1, l] = True
            t, l, b, r = t + 2, l + 2, b - 2, r - 2
    heat = np.where(mask, 1.0 + (y * w + x) % 7, 0.0)
    check_labels(heat, 0.5)


def _old_blob_boxes(hm: HeatMap, labels: np.ndarray) -> Detections:
    """HeatMap._blob_boxes as it was with scipy.ndimage.find_objects (the reference)."""
    cfg, c = hm.config, int(hm.config.cell)
    h, w = hm.frame_shape
    ext = float(cfg.extent)
    owner = np.zeros(0, np.int64)
    split = float(cfg.split_gap) > 0 and len(hm._cur[0]) > 1
    if (cfg.box_mode == "mean" or split) and len(hm._cur[0]):
        cb = hm._cur[0]
        cy = np.clip(((cb[:, 1] + cb[:, 3]) / 2 / c).astype(np.int64), 0, labels.shape[0] - 1)
        cx = np.clip(((cb[:, 0] + cb[:, 2]) / 2 / c).astype(np.int64), 0, labels.shape[1] - 1)
        owner = labels[cy, cx]
    boxes_l, peaks_l = [], []
    for i, sl in enumerate(ndimage.find_objects(labels)):
        if sl is None:
            continue
        blob = labels[sl] == i + 1
        hv = hm.heat[sl]
        y0, x0 = sl[0].start, sl[1].start
        mine = owner == i + 1
        for part in (hm._split(blob, x0, mine) if split else [blob]):
            pk = hv[part].max()
            ys, xs = np.nonzero(part & (hv >= ext * pk)) if ext > 0 else np.nonzero(part)
            y1, y2, x1, x2 = y0 + ys.min(), y0 + ys.max() + 1, x0 + xs.min(), x0 + xs.max() + 1
            box = (int(x1 * c), int(y1 * c), int(min(x2 * c, w)), int(min(y2 * c, h)))
            if cfg.box_mode == "mean" and mine.any():
                wts = hm._cur[1][mine]
                mb = (hm._cur[0][mine] * wts[:, None]).sum(0) / wts.sum()
                box = tuple(int(v) for v in np.clip(np.round(mb), 0, [w, h, w, h]))
            boxes_l.append(box)
            peaks_l.append(pk)
    return Detections(np.array(boxes_l, np.int32).reshape(-1, 4), np.array(peaks_l, np.float32))


def _old_weak(hm: HeatMap, thr: float) -> Detections:
    labels, n = ndimage.label(hm.heat > thr)
    if n == 0:
        return Detections.empty()
    d = _old_blob_boxes(hm, labels.astype(np.int32))
    return d[hm._shape_ok(d.boxes) & (d.scores <= hm.config.threshold)]


def assert_same(a: Detections, b: Detections) -> None:
    np.testing.assert_array_equal(a.boxes, b.boxes)
    np.testing.assert_array_equal(a.scores, b.scores)
    assert a.boxes.dtype == b.boxes.dtype and a.scores.dtype == b.scores.dtype


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(0, 30), frames=st.integers(1, 4),
       mode=st.sampled_from(["extent", "mean", "split"]), extent=st.sampled_from([0.0, 0.3, 0.6]))
def test_blob_boxes_same_as_scipy_version(seed, n, frames, mode, extent):
    rng = np.random.default_rng(seed)
    h, w = 90, 160
    kw = dict(box_mode="mean") if mode == "mean" else dict(split_gap=0.5) if mode == "split" else {}
    cfg = HeatConfig(n_frames=3, threshold=1.5, extent=extent, min_width=0, min_height=0, max_aspect=100.0, **kw)
    hm = HeatMap((h, w), cfg)
    for _ in range(frames):
        x1 = rng.integers(-10, w, n)
        y1 = rng.integers(-10, h, n)
        s = rng.integers(8, 40, n)
        boxes = np.stack([x1, y1, x1 + s, y1 + s], 1)
        got = hm.update(Detections(boxes.astype(np.int32), rng.normal(0.5, 1, n).astype(np.float32)))
    labels, _ = ndimage.label(hm.heat > cfg.threshold)
    np.testing.assert_array_equal(hm.labels, labels)
    ref = _old_blob_boxes(hm, labels.astype(np.int32))
    assert_same(hm.blobs, ref)
    assert_same(got, ref[hm._shape_ok(ref.boxes)])
    assert_same(hm.weak_boxes(0.5), _old_weak(hm, 0.5))


def test_blob_boxes_same_as_scipy_version_on_real_frames(data):
    """A few frames of the bundled clip through the video pipeline: both heat maps' labels,
    boxes and weak boxes as the SciPy-based code gave them."""
    from fastdet.io.reader import FrameReader
    from fastdet.video import VideoDetector

    reader = FrameReader(data / "videos" / "test_small1.mp4", 0, 12, notify=lambda _n: None)
    vd = VideoDetector(config=PipelineConfig(horizon=None), fps=reader.fps)
    checked = 0
    try:
        for _, frame, _ in reader:
            vd.update(frame)
            for hm in (vd.heatmap, vd.oncoming_heatmap):
                if hm is None or not hm.n_seen:
                    continue
                labels, _ = ndimage.label(hm.heat > hm.config.threshold)
                np.testing.assert_array_equal(hm.labels, labels)
                assert_same(hm.blobs, _old_blob_boxes(hm, labels.astype(np.int32)))
                for f in (0.3, 0.5):
                    assert_same(hm.weak_boxes(f * hm.config.threshold), _old_weak(hm, f * hm.config.threshold))
                checked += int(labels.max() > 0)
    finally:
        reader.close()
    assert checked > 0

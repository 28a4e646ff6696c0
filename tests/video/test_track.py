"""The tracker (fastdet.video.track, kalman, offline, count) on hand-made tracks, and its
parts against plain references: the batched Kalman filter against the textbook equations
one track at a time, the Hungarian assignment against trying every matching."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import HeatConfig, TrackerConfig
from fastdet.detections import Detections
from fastdet.video.count import CountLine, VehicleCounter
from fastdet.video.heatmap import HeatMap
from fastdet.video.kalman import BoxKalman, cxcywh_to_xyxy, xyxy_to_cxcywh
from fastdet.video.offline import extend_back, interpolate_gaps, offline_pass
from fastdet.video.track import LOST, TRACKED, Tracker, assign, buffered, split_merged


def dets(*boxes, score: float = 10.0) -> Detections:
    b = np.array(boxes, np.float64).reshape(-1, 4)
    return Detections(np.round(b).astype(np.int32), np.full(len(b), score, np.float32))


def car(x0: float, f: int, v: float = 8.0, y: float = 100.0, w: float = 60.0, h: float = 30.0) -> list[float]:
    """A car's box in frame ``f`` (0-based), starting at ``x0``, moving ``v`` px per frame."""
    x = x0 + v * f
    return [x, y, x + w, y + h]


def ids_of(out: Detections) -> list[int]:
    return [int(i) for i in out.ids]


# ------------------------------------------------------------------ references


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


def brute_force_assign(ious: np.ndarray, min_iou: float) -> float:
    """The best total ``IoU - min_iou`` over every matching of allowed pairs (plain search)."""
    n, m = ious.shape
    best = 0.0
    for k in range(1, min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                v = ious[list(rows), list(cols)]
                if (v >= min_iou).all():
                    best = max(best, float((v - min_iou).sum()))
    return best


@pytest.mark.parametrize("seed", range(25))
def test_assign_finds_the_best_matching(seed):
    rng = np.random.default_rng(seed)
    n, m = rng.integers(1, 5), rng.integers(1, 5)
    ious = np.where(rng.random((n, m)) < 0.6, rng.random((n, m)), 0.0)
    r, c = assign(ious, 0.3)
    assert len(set(r.tolist())) == len(r) and len(set(c.tolist())) == len(c)
    assert (ious[r, c] >= 0.3).all()
    assert float((ious[r, c] - 0.3).sum()) == pytest.approx(brute_force_assign(ious, 0.3))


def scipy_assign(ious: np.ndarray, min_iou: float) -> tuple[np.ndarray, np.ndarray]:
    """assign() as it was: always scipy.optimize.linear_sum_assignment (the reference)."""
    from scipy.optimize import linear_sum_assignment

    ok = ious >= min_iou
    if ious.size == 0 or not ok.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    r, c = linear_sum_assignment(np.where(ok, ious - min_iou, 0.0), maximize=True)
    keep = ok[r, c]
    return r[keep].astype(np.int64), c[keep].astype(np.int64)


@settings(max_examples=400, deadline=None)
@given(n=st.integers(0, 7), m=st.integers(0, 7), seed=st.integers(0, 2**31 - 1), p=st.floats(0, 1),
       exact=st.booleans())
def test_assign_same_pairs_as_the_solver(n, m, seed, p, exact):
    """The shortcut for conflict-free matrices gives the solver's pairs, in the same order;
    ``exact`` puts some IoUs exactly at the threshold (gain 0: left to the solver)."""
    rng = np.random.default_rng(seed)
    ious = np.where(rng.random((n, m)) < p, rng.random((n, m)), 0.0)
    if exact and ious.size:
        ious[rng.random((n, m)) < 0.3] = 0.3
    for thr in (0.3, 0.6):
        r, c = assign(ious, thr)
        rr, cc = scipy_assign(ious, thr)
        np.testing.assert_array_equal(r, rr)
        np.testing.assert_array_equal(c, cc)
        assert r.dtype == np.int64 and c.dtype == np.int64


def test_assign_prefers_the_pairs_that_beat_the_threshold_most():
    # track 0 overlaps box 0 (0.9) and box 1 (0.5); track 1 only box 0 (0.6). Gains over 0.2:
    # {0-0} = 0.7, {0-1, 1-0} = 0.3 + 0.4 = 0.7 -- a tie broken either way; at 0.4:
    # {0-0} = 0.5 beats {0-1, 1-0} = 0.1 + 0.2.
    ious = np.array([[0.9, 0.5], [0.6, 0.0]])
    r, c = assign(ious, 0.4)
    assert list(zip(r, c)) == [(0, 0)]
    assert assign(np.zeros((0, 3)), 0.2)[0].size == 0
    assert assign(np.full((2, 2), 0.1), 0.2)[0].size == 0


def test_buffered_boxes():
    np.testing.assert_allclose(buffered([[10, 20, 50, 40]], 0.5), [[-10, 10, 70, 50]])
    np.testing.assert_allclose(buffered([[10, 20, 50, 40]], 0.0), [[10, 20, 50, 40]])


def test_split_merged_cuts_between_predicted_boxes():
    # one box around two predicted cars side by side: cut half way between the left car's
    # right edge (160) and the right car's left edge (170): at 165
    parts, src = split_merged([[100, 50, 230, 80]], [[100, 52, 160, 78], [170, 50, 230, 80]], 0.5)
    np.testing.assert_allclose(parts, [[100, 50, 165, 80], [165, 50, 230, 80]])
    assert src.tolist() == [0, 0]
    # a box that holds only one predicted box, or too little of two, is passed through
    parts, src = split_merged([[100, 50, 160, 80], [300, 0, 340, 20]],
                              [[100, 50, 160, 80], [150, 50, 210, 80]], 0.5)
    np.testing.assert_allclose(parts, [[100, 50, 160, 80], [300, 0, 340, 20]])
    assert src.tolist() == [0, 1]
    parts, _ = split_merged([[0, 0, 100, 10]], [[0, 0, 40, 10], [60, 0, 100, 10]], 0.0)
    assert len(parts) == 1  # 0 turns the split off


# ------------------------------------------------------------------ tracker on hand-made tracks


def run(frames: list[Detections], config: TrackerConfig | None = None,
        low: list[Detections | None] | None = None) -> list[Detections]:
    tr = Tracker(config)
    return [tr.update(d, None if low is None else low[k]) for k, d in enumerate(frames)]


def test_one_car_keeps_id_1_and_its_detection_boxes():
    frames = [dets(car(0, f)) for f in range(20)]
    out = run(frames)
    assert all(ids_of(o) == [1] for o in out)
    for o, d in zip(out, frames):
        np.testing.assert_array_equal(o.boxes, d.boxes)
        np.testing.assert_array_equal(o.scores, d.scores)


def test_filtered_output_smooths_towards_the_track():
    rng = np.random.default_rng(0)
    truth = [car(0, f) for f in range(30)]
    noisy = [dets(np.array(b) + rng.normal(0, 3, 4)) for b in truth]
    out = run(noisy, TrackerConfig(output="filtered"))
    assert all(ids_of(o) == [1] for o in out)
    err_det = np.mean([np.abs(d.boxes[0] - t).mean() for d, t in zip(noisy[10:], truth[10:])])
    err_out = np.mean([np.abs(o.boxes[0] - t).mean() for o, t in zip(out[10:], truth[10:])])
    assert err_out < err_det


def test_two_cars_crossing_keep_their_ids():
    # car A left to right, car B right to left, one lane apart: their boxes overlap for
    # several frames around frame 20; the filters' velocities keep the ids apart
    frames = [dets(car(0, f, 10, y=100), car(400, f, -10, y=110)) for f in range(40)]
    out = run(frames)
    for f, o in enumerate(out):
        assert sorted(ids_of(o)) == [1, 2], f
        a = o.boxes[o.ids == 1][0]
        assert abs(a[0] - car(0, f, 10)[0]) <= 1, f  # id 1 is still car A


def test_occlusion_of_a_few_frames_keeps_the_id():
    frames = [dets(car(0, f)) if not 10 <= f < 14 else dets() for f in range(25)]
    out = run(frames)
    for f, o in enumerate(out):
        assert ids_of(o) == ([] if 10 <= f < 14 else [1]), f


def test_offline_pass_fills_the_occlusion():
    frames = [dets(car(0, f)) if not 10 <= f < 14 else dets() for f in range(25)]
    out = offline_pass(list(enumerate(run(frames), start=1)), (480, 640))
    for f, (fno, o) in enumerate(out):
        assert fno == f + 1 and ids_of(o) == [1], f
        if 10 <= f < 14:
            assert o.scores[0] == 0.0  # added by the offline pass
            np.testing.assert_array_equal(o.boxes[0], np.round(car(0, f)))
        else:
            assert o.scores[0] == 10.0


def test_a_new_car_gets_the_next_id_and_the_first_keeps_its_own():
    frames = [dets(*([car(0, f)] + ([car(300, f, -5)] if f >= 10 else []))) for f in range(20)]
    out = run(frames)
    assert all(ids_of(o) == [1] for o in out[:10])
    assert all(ids_of(o) == [1, 2] for o in out[10:])
    assert abs(out[-1].boxes[out[-1].ids == 2][0][0] - car(300, 19, -5)[0]) <= 1


def test_a_car_that_left_is_forgotten_after_max_lost():
    cfg = TrackerConfig(max_lost=5)
    box = car(100, 0, 0)
    frames = [dets(box)] * 5 + [dets()] * 6 + [dets(box)] * 3
    tr = Tracker(cfg)
    out = [tr.update(d) for d in frames]
    assert all(ids_of(o) == [1] for o in out[:5])
    assert all(len(o) == 0 for o in out[5:11])
    assert all(ids_of(o) == [2] for o in out[11:])  # came back after 6 > 5 frames: a new vehicle
    # within max_lost, the same id
    frames = [dets(box)] * 5 + [dets()] * 5 + [dets(box)] * 3
    out = run(frames, cfg)
    assert all(ids_of(o) == [1] for o in out[5 + 5:])


def test_track_states_tracked_then_lost():
    tr = Tracker()
    tr.update(dets(car(0, 0)))
    assert [(t.id, t.state) for t in tr.tracks] == [(1, TRACKED)]
    tr.update(dets())
    assert [(t.id, t.state) for t in tr.tracks] == [(1, LOST)]
    assert tr.confirmed == 1


def test_low_confidence_boxes_keep_a_track_alive_but_never_start_one():
    high = [dets(car(0, f)) if not 8 <= f < 12 else dets() for f in range(16)]
    low = [dets(car(0, f), score=2.0) if 8 <= f < 12 else None for f in range(16)]
    out = run(high, low=low)
    for f, o in enumerate(out):
        assert ids_of(o) == [1], f
        assert o.scores[0] == (2.0 if 8 <= f < 12 else 10.0)
    # low boxes alone start nothing
    out = run([dets()] * 5, low=[dets(car(0, f), score=2.0) for f in range(5)])
    assert all(len(o) == 0 for o in out)


def test_min_hits_confirms_late_and_drops_one_frame_blips():
    cfg = TrackerConfig(min_hits=3)
    frames = [dets(*([car(0, f)] + ([car(400, 0, 0)] if f == 2 else []))) for f in range(8)]
    out = run(frames, cfg)
    assert [ids_of(o) for o in out] == [[], [], [1], [1], [1], [1], [1], [1]]


def test_ids_restart_at_1_after_reset_and_for_a_new_tracker():
    frames = [dets(car(0, f), car(300, f)) for f in range(5)]
    tr = Tracker()
    first = [ids_of(tr.update(d)) for d in frames]
    tr.reset()
    again = [ids_of(tr.update(d)) for d in frames]
    assert first == again == [[1, 2]] * 5
    assert [ids_of(o) for o in run(frames)] == first


def test_merged_blob_of_two_tracked_cars_is_split_with_two_ids():
    # two cars side by side, 10 px apart, moving together; for frames 10..14 the detector
    # gives one box around both (their blobs merged)
    def pair(f):
        return car(100, f, 4), car(170, f, 4)

    frames = []
    for f in range(20):
        a, b = pair(f)
        frames.append(dets([a[0], a[1], b[2], b[3]]) if 10 <= f < 15 else dets(a, b))
    out = run(frames)
    for f, o in enumerate(out):
        assert ids_of(o) == [1, 2], f
        a, b = pair(f)
        assert o.boxes[0][2] <= b[0] + 6 and o.boxes[1][0] >= a[2] - 6, f  # cut in the gap
    # without the split the merged box goes to one track only
    out = run(frames, TrackerConfig(split_overlap=0))
    assert all(len(o) == 1 for o in out[10:15])


def test_tracker_config_is_checked():
    with pytest.raises(ValueError):
        TrackerConfig(low_heat=1.5)
    with pytest.raises(ValueError):
        TrackerConfig(min_hits=0)
    with pytest.raises(ValueError):
        TrackerConfig(output="kalman")
    with pytest.raises(TypeError):
        Tracker(HeatConfig())
    assert TrackerConfig.from_dict(TrackerConfig().to_dict()) == TrackerConfig()


# ------------------------------------------------------------------ offline pass


def test_interpolate_gaps_linear_and_bounded():
    tr = [(1, np.array([0.0, 0, 10, 10])), (4, np.array([30.0, 0, 40, 10])), (20, np.array([0.0, 0, 10, 10]))]
    got = interpolate_gaps(tr, max_gap=5)
    assert [f for f, _ in got] == [2, 3]
    np.testing.assert_allclose(got[0][1], [10, 0, 20, 10])
    np.testing.assert_allclose(got[1][1], [20, 0, 30, 10])


def test_extend_back_moves_the_first_box_at_the_starting_velocity():
    tr = [(10, np.array([100.0, 50, 140, 70])), (11, np.array([90.0, 50, 134, 72]))]
    # centre velocity (-8, +1) per frame; the first box's size is kept
    got = extend_back(tr, 3, first_frame=1, frame_shape=(480, 640))
    assert [f for f, _ in got] == [7, 8, 9]
    np.testing.assert_allclose(got[-1][1], [108, 49, 148, 69])
    np.testing.assert_allclose(got[0][1], [124, 47, 164, 67])
    assert [f for f, _ in extend_back(tr, 3, first_frame=9, frame_shape=(480, 640))] == [9]
    # stops where less than half the box would be in the picture
    tr = [(10, np.array([0.0, 50, 40, 70])), (11, np.array([30.0, 50, 70, 70]))]
    assert extend_back(tr, 3, 1, (480, 640)) == []


def test_offline_pass_keeps_frames_and_adds_nothing_without_ids():
    frames = [(1, dets(car(0, 0))), (2, Detections.empty())]
    assert [len(d) for _, d in offline_pass(frames, (480, 640))] == [1, 0]
    assert offline_pass([], (480, 640)) == []


# ------------------------------------------------------------------ counting


def test_count_line_sides_and_crossings():
    ln = CountLine(0, 100, 200, 100)  # drawn left to right: its right side is below it
    assert ln.side(np.array([[50, 150], [50, 50]])).tolist() == [10000.0, -10000.0]
    assert ln.crossed(np.array([50, 90]), np.array([50, 110])) == 1  # downwards: left -> right
    assert ln.crossed(np.array([50, 110]), np.array([50, 90])) == -1
    assert ln.crossed(np.array([250, 90]), np.array([250, 110])) == 0  # past the segment's end
    assert ln.crossed(np.array([50, 90]), np.array([60, 95])) == 0
    assert ln.crossed(np.array([50, 90]), np.array([50, 100])) == 0  # touching is not crossing
    assert CountLine.parse(" 1, 2,3,4") == CountLine(1, 2, 3, 4)
    for bad in ("1,2,3", "a,b,c,d", "1,2,1,2", "1,2,3,inf"):
        with pytest.raises(ValueError):
            CountLine.parse(bad)


def test_vehicle_counter_counts_ids_and_crossings_once_per_direction():
    # car 1 moves right across a vertical line at x = 200 (bottom centre from x = 130);
    # car 2 waits left of it; car 3 goes right then comes back
    line = CountLine(200, 0, 200, 480)  # drawn downwards: its right side is the picture's left
    c = VehicleCounter(line)
    for f in range(20):
        b1 = car(100, f, 10)
        b2 = car(0, 0, 0)
        x3 = 150 + (10 * f if f < 10 else 10 * (20 - f))
        c.update(Detections(np.array([b1, b2, [x3, 300, x3 + 40, 330]], np.int32), np.ones(3, np.float32),
                            ids=np.array([1, 2, 3])))
    assert c.vehicles == 3
    s = c.summary()
    assert s["line"]["right_to_left"] == 2  # cars 1 and 3 went left -> right in the picture
    assert s["line"]["left_to_right"] == 1  # car 3 came back
    assert "3 vehicles" in c.text() and "2 right to left" in c.text()
    assert VehicleCounter().summary() == {"vehicles": 0}


def test_vehicle_counter_leaves_out_glimpses():
    # id 1 seen in 5 frames, id 2 in 2 (crossing the line meanwhile): only id 1 counts
    c = VehicleCounter(CountLine(0, 100, 200, 100), min_frames=3)
    for f in range(5):
        boxes = [[10, 50, 50, 80]] + ([[100, 60 + 40 * f, 140, 90 + 40 * f]] if f < 2 else [])
        c.update(Detections(np.array(boxes, np.int32), np.ones(len(boxes), np.float32),
                            ids=np.arange(1, len(boxes) + 1)))
    assert c.vehicles == 1 and c.ids == {1}
    assert c.crossed["left_to_right"] == {2} and c.crossings() == {"left_to_right": 0, "right_to_left": 0}
    assert VehicleCounter(min_frames=1).min_frames == 1
    with pytest.raises(ValueError):
        VehicleCounter(min_frames=0)


# ------------------------------------------------------------------ weak boxes of the heat map


def test_weak_boxes_are_the_blobs_below_the_threshold():
    cfg = HeatConfig(n_frames=1, threshold=4.0, extent=0.0, min_width=8, min_height=8, cell=4)
    hm = HeatMap((100, 200), cfg, score_kind="decision")
    # heat of a window: 1 + 3 * clip(score / 2, 0, 1). A strong place (three windows of
    # score 2: heat 12) and a weak one (scores 0 and 1: heat 1 + 2.5 = 3.5, not above 4)
    strong = [[10, 10, 42, 42]] * 3
    weak = [[120, 40, 152, 72]]
    windows = Detections(np.array(strong + weak + weak), np.array([2.0, 2.0, 2.0, 0.0, 1.0]))
    boxes = hm.update(windows)
    assert boxes.boxes.tolist() == [[12, 12, 44, 44]]
    w = hm.weak_boxes(1.0)
    assert w.boxes.tolist() == [[120, 40, 152, 72]]
    assert float(w.scores[0]) == 3.5
    assert len(hm.weak_boxes(3.5)) == 0  # its peak is not above 3.5
    assert hm.boxes().boxes.tolist() == boxes.boxes.tolist()  # boxes() is unchanged by it

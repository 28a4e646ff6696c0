"""The tracker (fastdet.video.track) on hand-made tracks, and its parts against plain
references: the Hungarian assignment against trying every matching. The Kalman filter, the
offline pass and counting: test_kalman.py, test_offline.py, test_count.py beside this file."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import HeatConfig, TrackerConfig
from fastdet.detections import Detections
from fastdet.video.heatmap import HeatMap
from fastdet.video.track import (
    LOST,
    TRACKED,
    Tracker,
    assign,
    buffered,
    outside_fraction,
    split_merged,
)


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


def test_a_car_missed_after_misplaced_boxes_keeps_its_id():
    """An oncoming car (48 x 24 px, 16 px a frame to the left, on one row) tracked for 4 frames
    whose last two boxes slip down by a quarter of their height each (heat-map boxes whose top
    and bottom jump), then missed for 3 frames, then found again on its row. The filter learnt
    a downward velocity from the two slipped boxes; extrapolated over the frames it is missed,
    the prediction ends below the car and the car would get a new id. A lost track keeps its
    row (``hold_row``), as it keeps its size, and the car keeps id 1."""
    def box(f: int) -> list[float]:
        b = car(600, f, -16, y=424, w=48, h=24)
        slip = {2: 6, 3: 12}.get(f, 0)
        return [b[0], b[1] + slip, b[2], b[3] + slip]

    frames = [dets() if 4 <= f < 7 else dets(box(f)) for f in range(12)]
    out = run(frames)
    assert [ids_of(o) for o in out] == [[1]] * 4 + [[]] * 3 + [[1]] * 5
    # the cause: without holding the row, the prediction drifts off the car and it gets id 2
    out = run(frames, TrackerConfig(hold_row=False))
    assert [ids_of(o) for o in out[7:]] == [[2]] * 5


def test_a_lost_track_keeps_its_row_and_size_but_moves_across():
    tr = Tracker()
    for f in range(6):  # a car drifting down-left and growing, then missed
        x, y, s = 600 - 16 * f, 400 + 3 * f, 1 + 0.05 * f
        tr.update(dets([x, y, x + 48 * s, y + 24 * s]))
    pred = []
    for _ in range(4):
        tr.update(dets())
        (t,) = tr.tracks
        assert t.state == LOST
        pred.append(t.predicted.copy())
    # from the second frame missed on: the same rows and size, still moving left ~16 px a frame
    for a, b in zip(pred[1:], pred[2:]):
        np.testing.assert_allclose(b[[1, 3]], a[[1, 3]])
        np.testing.assert_allclose(b[2] - b[0], a[2] - a[0])
        assert -18 < b[0] - a[0] < -14


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
    # the same when update is told the boxes are not blobs (split=False: the NMS boxes' tracker)
    tr = Tracker()
    out = [tr.update(d, split=False) for d in frames]
    assert all(len(o) == 1 for o in out[10:15])
    assert [ids_of(o) for o in out[:10]] == [[1, 2]] * 10


# ------------------------------------------------------------------ leaving through the border

FRAME = (360, 640)  # height, width


def outside_fraction_reference(box: list[int], frame_shape: tuple[int, int]) -> float:
    """The fraction of an integer box's pixels outside the picture, by counting them."""
    x1, y1, x2, y2 = box
    if x2 <= x1 or y2 <= y1:
        return 1.0
    h, w = frame_shape
    inside = sum(1 for y in range(y1, y2) for x in range(x1, x2) if 0 <= x < w and 0 <= y < h)
    return 1.0 - inside / ((x2 - x1) * (y2 - y1))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(-30, 50), st.integers(-30, 40), st.integers(-5, 40), st.integers(-5, 40)),
                min_size=1, max_size=6), st.integers(1, 30), st.integers(1, 30))
def test_outside_fraction_against_counting_pixels(spec, h, w):
    boxes = [[x, y, x + bw, y + bh] for x, y, bw, bh in spec]
    got = outside_fraction(np.array(boxes, np.float64), (h, w))
    want = [outside_fraction_reference(b, (h, w)) for b in boxes]
    np.testing.assert_allclose(got, want, atol=1e-12)


def leaving_then_entering(f: int) -> list[list[float]]:
    """Frame ``f`` at the left edge of a 640 x 360 picture: a car 50 px wide leaving slowly (2
    px a frame) whose box is cut at the border, found while at least 36 px of it show (frames
    0-27); from frame 40 another vehicle entering at the same edge, its box growing 4 px a frame."""
    x = 40 - 2 * f
    boxes = [[max(x, 0), 200, x + 50, 230]] if x + 50 >= 36 else []
    if f >= 40:
        boxes.append([0, 202, 30 + 4 * (f - 40), 234])
    return boxes


def run_in_frame(frames: list[Detections], config: TrackerConfig, frame_shape=FRAME) -> list[list[int]]:
    tr = Tracker(config)
    return [ids_of(tr.update(d, frame_shape=frame_shape)) for d in frames]


def test_a_track_that_left_through_the_border_does_not_pass_its_id_on():
    """The lost track of the car that left keeps its last (cut) size and moves at the speed of
    its box's centre, slower than the car: 12 frames after the car left, its prediction still
    overlaps the border where the next vehicle enters, which took id 1. With ``exit_outside``
    the track ends once a quarter of its prediction is outside, and the newcomer gets id 2."""
    frames = [dets(*leaving_then_entering(f)) for f in range(50)]
    assert run_in_frame(frames, TrackerConfig(exit_outside=None))[40:] == [[1]] * 10  # the cause
    assert TrackerConfig().exit_outside == 0.25
    out = run_in_frame(frames, TrackerConfig())
    assert out[:28] == [[1]] * 28 and out[28:40] == [[]] * 12 and out[40:] == [[2]] * 10
    # the same without the picture's size: nothing is dropped
    assert run_in_frame(frames, TrackerConfig(exit_outside=0.25), frame_shape=None)[40:] == [[1]] * 10


def test_a_car_missed_at_the_border_keeps_its_id():
    """A car alongside, a tenth of it outside the picture at the right edge and standing still
    there (its box cut at the border), missed for 5 frames: its prediction stays as far out as
    its box, below ``exit_outside``, and it keeps id 1; so does a lost car inside the picture."""
    cut = [600, 250, 640, 330]  # the car spans 596-640
    frames = [dets(cut)] * 10 + [dets()] * 5 + [dets(cut)] * 5
    assert run_in_frame(frames, TrackerConfig(exit_outside=0.25)) == [[1]] * 10 + [[]] * 5 + [[1]] * 5
    inside = [dets(car(0, f, 8, y=200)) if not 10 <= f < 15 else dets() for f in range(20)]
    assert run_in_frame(inside, TrackerConfig(exit_outside=0.0)) == [[1]] * 10 + [[]] * 5 + [[1]] * 5


def test_only_lost_tracks_end_at_the_border():
    """A tracked car whose prediction runs ahead of its cut boxes, well outside the picture,
    keeps its track and id while it is found: the rule reads lost tracks only."""
    frames = [dets([max(40 - 12 * f, 0), 200, 40 - 12 * f + 60, 230]) for f in range(8)]  # last: 4 px show
    tr = Tracker(TrackerConfig(exit_outside=0.25))
    for f, d in enumerate(frames):
        assert ids_of(tr.update(d, frame_shape=FRAME)) == [1], f
    assert outside_fraction(tr.tracks[0].predicted, FRAME)[0] > 0.25
    tr.update(dets(), frame_shape=FRAME)  # missed: lost, and now predicted further out
    assert [t.state for t in tr.tracks] == [LOST]
    tr.update(dets(), frame_shape=FRAME)  # one frame missed before this one: kept (exit_after 2)
    assert [t.state for t in tr.tracks] == [LOST]
    tr.update(dets(), frame_shape=FRAME)  # two missed, far outside: ended
    assert tr.tracks == []


def test_a_track_missed_once_at_the_border_is_kept():
    """A car leaving fast at the left edge (16 px a frame, its box cut) is missed for one frame
    and found again, cut, in the next: its prediction is then more than a quarter outside,
    but after a single missed frame (``exit_after`` 2) the track is kept and the remains of the
    car keep id 1; with ``exit_after=1`` the track ends and they get id 2."""
    def box(f: int) -> list[float]:
        x = 100 - 16 * f
        return [max(x, 0), 200, x + 60, 230]

    frames = [dets(box(f)) if f != 7 else dets() for f in range(9)]  # f 8: 12 px of it show
    tr = Tracker()
    out = [ids_of(tr.update(d, frame_shape=FRAME)) for d in frames]
    assert out == [[1]] * 7 + [[]] + [[1]]
    (t,) = tr.tracks
    assert outside_fraction(t.predicted, FRAME)[0] > 0.25  # where it was predicted in the last frame
    assert run_in_frame(frames, TrackerConfig(exit_after=1)) == [[1]] * 7 + [[]] + [[2]]


def test_tracker_refuses_a_config_of_another_kind():
    with pytest.raises(TypeError):
        Tracker(HeatConfig())


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

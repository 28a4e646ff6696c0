"""Search bands relative to the horizon, and the horizon estimated from the optical flow."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.config import REFERENCE_HORIZON, PipelineConfig, SearchBand, SearchConfig
from fastdet.video import horizon as horizon_module
from fastdet.video.horizon import (
    HORIZON_FRAMES,
    MAX_PAIRS,
    MAX_SPREAD,
    MIN_PAIRS,
    HorizonEstimator,
    estimate_horizon,
    focus_of_expansion,
    median_flow,
    search_horizon,
)
from fastdet.video.vanishing import vanishing_point
from tests.video.test_vanishing import _road

REF_ROW = REFERENCE_HORIZON * 720


def test_for_frame_moves_bands_with_the_horizon():
    cfg = SearchConfig(bands=(SearchBand(1.0, 400, 496), SearchBand(2.0, 400, 592, 100, 900)))
    up = SearchConfig(cfg.bands, horizon=0.485).for_frame((720, 1280))
    # 72 rows up, in whole window steps (2 cells of 8 x scale rows): 4 x 16 and 2 x 32 rows
    assert [(b.scale, b.y_start, b.y_stop, b.x_start, b.x_stop) for b in up.bands] == \
        [(1.0, 336, 432, None, None), (2.0, 336, 528, 100, 900)]
    assert up.horizon is None and up.reference_shape is None
    # at half the resolution: rows and scales halve, then 36 rows up in steps of 8 and 16
    half = SearchConfig(cfg.bands, horizon=0.485).for_frame((360, 640))
    assert [(b.scale, b.y_start, b.y_stop) for b in half.bands] == [(0.5, 168, 216), (1.0, 168, 264)]
    # 0.7 of a step down moves a band by one step, 0.3 of a step not at all
    assert SearchConfig(cfg.bands[:1], horizon=REFERENCE_HORIZON + 11.2 / 720).for_frame((720, 1280)).bands == \
        (SearchBand(1.0, 416, 512),)
    assert SearchConfig(cfg.bands[:1], horizon=REFERENCE_HORIZON + 4.8 / 720).for_frame((720, 1280)).bands == \
        cfg.bands[:1]
    # the reference horizon itself changes nothing
    assert SearchConfig(cfg.bands, horizon=REFERENCE_HORIZON).for_frame((720, 1280)).bands == cfg.bands


def test_for_frame_clips_and_drops_bands():
    cfg = SearchConfig(bands=(SearchBand(1.0, 400, 496), SearchBand(3.0, 400, 656)), horizon=0.9)
    out = cfg.for_frame((720, 1280))  # +227 rows: 224 (14 steps) and 240: too low for 192-px windows
    assert [(b.scale, b.y_start, b.y_stop) for b in out.bands] == [(1.0, 624, 720)]
    with pytest.raises(ValueError, match="no search band"):
        SearchConfig(bands=(SearchBand(1.0, 400, 496),), horizon=1.0).for_frame((720, 1280))
    with pytest.raises(ValueError):
        SearchConfig(horizon=1.5)


def test_detector_set_horizon_moves_both_searches():
    from fastdet.video import make_detector

    det = make_detector()
    before = {p: [(g.y0, g.y1) for g in det.geometries((720, 1280), p)] for p in (0, 1)}
    det.set_horizon(REFERENCE_HORIZON - 0.1)
    assert det.horizon == pytest.approx(REFERENCE_HORIZON - 0.1)
    after = {p: [(g.y0, g.y1) for g in det.geometries((720, 1280), p)] for p in (0, 1)}
    for p in (0, 1):
        for g, (a, b), (a2, b2) in zip(det.geometries((720, 1280), p), before[p], after[p]):
            step = 8 * g.band.scale * det.scorers[p].search.cells_per_step
            moved = a - a2
            assert moved == b - b2 and abs(moved - 72) <= step / 2 + 0.5  # the nearest whole steps
            assert abs(moved / step - round(moved / step)) < 0.07  # (rounded to whole rows)
    det.set_horizon(None)
    assert {p: [(g.y0, g.y1) for g in det.geometries((720, 1280), p)] for p in (0, 1)} == before


def _texture(h: int, w: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 8, w // 8, 3), dtype=np.uint8)
    return cv2.GaussianBlur(cv2.resize(small, (w, h), interpolation=cv2.INTER_NEAREST), (5, 5), 0)


def _zoom_about(img: np.ndarray, x0: float, y0: float, z: float) -> np.ndarray:
    m = np.array([[z, 0, (1 - z) * x0], [0, z, (1 - z) * y0]])
    return cv2.warpAffine(img, m, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


@pytest.mark.parametrize("fx, fy", [(640, 300), (500, 420), (700, 200)])
def test_focus_of_expansion_of_a_zoom(fx, fy):
    img = _texture(720, 1280)
    foe = focus_of_expansion(img, _zoom_about(img, fx, fy, 1.03))
    assert foe is not None
    assert foe == pytest.approx((fx, fy), abs=6)


def test_no_estimate_without_motion():
    img = _texture(360, 640)
    assert focus_of_expansion(img, img) is None
    assert estimate_horizon([img] * 20) is None


def test_estimator_takes_the_median_of_pairs():
    img = _texture(360, 640, seed=1)
    frames = [_zoom_about(img, 320, 150, 1.02 ** k) for k in range(20)]
    est = HorizonEstimator(gap=1, every=1, min_pairs=5)
    for f in frames:
        est.update(f)
    assert len(est.rows) >= 5
    assert est.estimate == pytest.approx(150 / 360, abs=0.01)
    assert estimate_horizon(frames, gap=1, every=1) == pytest.approx(est.estimate)


def test_search_horizon_tolerance():
    assert search_horizon(None) is None
    assert search_horizon(REFERENCE_HORIZON + 0.005) is None
    assert search_horizon(REFERENCE_HORIZON - 0.05) == pytest.approx(REFERENCE_HORIZON - 0.05)


def _zoom_frames(n: int, y0: float, shape=(360, 640)) -> list[np.ndarray]:
    img = _texture(*shape, seed=2)
    return [_zoom_about(img, shape[1] / 2, y0, 1.02 ** k) for k in range(n)]


def test_video_detector_horizon_settings():
    from fastdet.video import VideoDetector, make_detector

    det = make_detector()
    frame = _zoom_frames(1, 150)[0]
    vd = VideoDetector(det, PipelineConfig(horizon=0.5))
    vd.update(frame)
    assert det.horizon == pytest.approx(0.5)
    det.set_horizon(0.45)
    VideoDetector(det, PipelineConfig(horizon=None)).update(frame)
    assert det.horizon == pytest.approx(0.45)  # None: the detector's own search
    with pytest.raises(ValueError):
        VideoDetector(det, PipelineConfig(horizon=1.5))
    with pytest.raises(ValueError):
        VideoDetector(det, PipelineConfig(horizon="middle"))


def test_video_detector_estimates_the_horizon():
    from fastdet.video import VideoDetector, make_detector

    det = make_detector()
    frames = _zoom_frames(24, 150)  # the picture expands from row 150 of 360
    vd = VideoDetector(det)  # horizon='auto'
    assert vd.prime_horizon(frames) == pytest.approx(150 / 360, abs=0.01)
    assert det.horizon == pytest.approx(150 / 360, abs=0.01)
    vd.reset()  # a cut: the same camera, the horizon stays
    vd.update(frames[0])
    assert det.horizon == pytest.approx(150 / 360, abs=0.01)
    vd = VideoDetector(det)  # another video: back to the reference until it has an estimate of its own
    vd.update(frames[0])
    assert det.horizon is None
    for f in frames[1:]:  # online: the estimate arrives after MIN_PAIRS pairs
        vd.update(f)
    assert det.horizon == pytest.approx(150 / 360, abs=0.01)
    from fastdet.video.stages import HorizonStage

    est = vd.stage(HorizonStage).estimator
    n = len(est.rows) if est is not None else None
    vd.reset()
    vd.update(frames[0])  # no pair across the cut
    est = vd.stage(HorizonStage).estimator
    assert est is None or len(est.rows) == n
    # still pictures give no estimate: the reference bands
    vd2 = VideoDetector(det)
    assert vd2.prime_horizon([frames[0]] * 20) is None and det.horizon is None


@pytest.mark.parametrize("start", [0, 7])
def test_video_detector_for_primes_from_the_run_reader(data, start, monkeypatch):
    """video_detector_for takes the first seconds from the run's reader (peek): the same
    horizon as a second reader of the file gives, the file decoded once, every frame still
    yielded; over the buffer limit (or a run shorter than the priming) it decodes them again."""
    from fastdet.io.reader import FrameReader
    from fastdet.video import VideoDetector, make_detector, prime_horizon_from_file, video_detector_for
    from fastdet.video import run as pipeline

    path = data / "videos" / "test_small1.mp4"
    det = make_detector()
    prime_horizon_from_file(VideoDetector(det), path, start)
    want = det.horizon
    opened = []
    real = pipeline.FrameReader

    class Counting(real):
        def __init__(self, *a, **k):
            opened.append(a[0])
            super().__init__(*a, **k)

    monkeypatch.setattr(pipeline, "FrameReader", Counting)
    with FrameReader(path, start, notify=lambda _n: None) as r:
        det.set_horizon(None)
        video_detector_for(r, det)
        assert det.horizon == want and opened == []
        assert [fno for fno, *_ in r][:3] == [start + 1, start + 2, start + 3]
    monkeypatch.setattr(pipeline, "PRIME_BUFFER_BYTES", 1000)
    with FrameReader(path, start, notify=lambda _n: None) as r:
        det.set_horizon(None)
        video_detector_for(r, det)
        assert det.horizon == want and len(opened) == 1


def test_estimator_refuses_bad_settings():
    with pytest.raises(ValueError):
        HorizonEstimator(gap=0)
    with pytest.raises(ValueError):
        HorizonEstimator(min_pairs=5, max_pairs=4)

def test_median_flow_is_the_shift_in_work_pixels():
    img = _texture(720, 1280, seed=2)
    shifted = cv2.warpAffine(img, np.float32([[1, 0, 6], [0, 1, 0]]), (1280, 720), borderMode=cv2.BORDER_REFLECT)
    assert median_flow(img, shifted) == pytest.approx(3.0, abs=0.3)  # 6 px at 720 rows: 3 at 360
    assert median_flow(img, shifted, work_rows=720) == pytest.approx(6.0, abs=0.5)
    assert median_flow(img, img) == pytest.approx(0.0, abs=1e-3)
    flat = np.full((360, 640, 3), 90, np.uint8)
    assert median_flow(flat, flat) == 0.0  # no corners to track


def _eager_horizon(frames, every=3):
    """The default estimator with the segments' fallback measured at once, a plain reference:
    while the flow has no estimate, the vanishing point of every ``every``-th frame is found
    as the frame arrives. ``(estimate, source, segment rows, frames used)``."""
    flow = HorizonEstimator(every=every, segments=False)
    seg: list[float] = []
    used = 0
    for k, f in enumerate(frames[:HORIZON_FRAMES]):
        if len(flow.rows) >= MAX_PAIRS and (flow.estimate is not None or len(seg) >= MAX_PAIRS):
            break  # done
        flow.update(f)
        used += 1
        if k % every == 0 and len(seg) < MAX_PAIRS and flow.estimate is None:
            v = vanishing_point(f)
            if v is not None:
                seg.append(v[1] / f.shape[0])
    if flow.estimate is not None:
        return flow.estimate, "flow", seg, used
    est = None
    if len(seg) >= MIN_PAIRS and (len(flow.rows) >= MIN_PAIRS or len(seg) >= MAX_PAIRS):
        med = float(np.median(seg))
        est = med if float(np.median(np.abs(np.asarray(seg) - med))) <= MAX_SPREAD else None
    return est, ("segments" if est is not None else None), seg, used


def _lazy_horizon(frames, online: bool, **kw):
    """The estimator as the video pipeline drives it: ``online``, the estimate asked after
    every frame (HorizonStage on a stream); else only ``done`` until the end (priming)."""
    est = HorizonEstimator(**kw)
    used = 0
    for f in frames[:HORIZON_FRAMES]:
        if est.done:
            break
        est.update(f)
        used += 1
        if online:
            est.estimate  # noqa: B018 - asked as the stage asks it
    return est, used


def _counting_segments(monkeypatch) -> list[int]:
    calls: list[int] = []
    real = horizon_module.vanishing_point

    def counted(frame):
        calls.append(1)
        return real(frame)

    monkeypatch.setattr(horizon_module, "vanishing_point", counted)
    return calls


def test_segments_are_found_only_when_the_flow_fails(monkeypatch):
    calls = _counting_segments(monkeypatch)
    frames = _zoom_frames(24, 150)  # the flow agrees from its first pairs on
    for online in (False, True):
        calls.clear()
        est, _ = _lazy_horizon(frames, online, gap=1, every=1)
        assert est.source == "flow" and calls == []
        ref = _eager_horizon(frames, every=1)
        # asked for, the rows are measured: the frames 0-4, before the fifth pair gave the flow its say
        assert est.segment_rows == ref[2] and len(calls) == 5
    still = [_road(320, 150)] * 20  # a camera standing still: the flow never has its say
    calls.clear()
    est, _ = _lazy_horizon(still, True, gap=1, every=1, max_pairs=6)
    # measured once 6 frames could give the 6 rows that let the segments speak, then no more
    assert len(calls) == 6 and est.source == "segments" and len(est.segment_rows) == 6


@pytest.mark.slow
def test_lazy_segments_give_the_eager_estimates_on_every_clip(data, monkeypatch):
    """On all five clips the estimate, its source, the vanishing-point rows and the frames
    used are those of the eager reference (the estimate asked after every frame, as on a
    stream); the clips whose flow gives the estimate run the segment detector on no frame."""
    from fastdet.eval.clips import annotated_clips
    from fastdet.io.reader import read_frames

    calls = _counting_segments(monkeypatch)
    for clip in annotated_clips(data):
        frames = read_frames(clip.video, frames=HORIZON_FRAMES, notify=lambda _n: None)
        ref = _eager_horizon(frames)
        calls.clear()
        est, used = _lazy_horizon(frames, online=True)
        found = len(calls)
        assert (est.estimate, est.source, est.segment_rows, used) == ref, clip.name
        if ref[1] == "flow":
            assert found == 0, clip.name


@pytest.mark.parametrize("clip,start", [("test_small1", 0), ("test_small1", 70), ("boston_street", 0),
                                        ("boston_street", 32)])
def test_file_horizon_is_where_a_run_from_there_searches(data, clip, start):
    """file_horizon(path, start) is the horizon a run of the file from ``start`` primes its bands
    to (None where it has no estimate: the last 8 frames of boston_street give none, its first
    40 one), and PipelineConfig(horizon=it) puts them there without reading ahead."""
    from fastdet.video import VideoDetector, make_detector, prime_horizon_from_file
    from fastdet.video.run import file_horizon

    path = data / "videos" / f"{clip}.mp4"
    det = make_detector()
    prime_horizon_from_file(VideoDetector(det), path, start)
    got = file_horizon(path, start)
    assert got == det.horizon
    if (clip, start) == ("boston_street", 0):
        assert got is not None
    if (clip, start) == ("boston_street", 32):
        assert got is None
    if got is not None:
        fixed = make_detector()
        vd = VideoDetector(fixed, PipelineConfig(horizon=got))
        vd.update(np.zeros({"test_small1": (720, 1280, 3), "boston_street": (450, 800, 3)}[clip], np.uint8))
        assert fixed.horizon == got


# --------------------------------------------------------------------------------------
# the horizon a camera's labelled vehicles imply (adapt's choice against the flow's)
# --------------------------------------------------------------------------------------
def _perspective_boxes(n: int, horizon: float, height: int, k: float = 0.8, seed: int = 0,
                       outliers: int = 0) -> np.ndarray:
    """Boxes of vehicles on a level road seen by a camera whose horizon is at ``horizon``: the
    bottom row ``horizon x height + k x width`` (+- 2 px), ``outliers`` of them anywhere."""
    rng = np.random.default_rng(seed)
    w = rng.uniform(20, 300, n)
    yb = horizon * height + k * w + rng.normal(0, 2, n)
    yb[:outliers] = rng.uniform(0, height - 2, outliers)
    x1 = rng.uniform(0, 900, n)
    return np.c_[x1, yb - 0.8 * w, x1 + w, np.minimum(yb, height - 2)]


@pytest.mark.parametrize("horizon", [0.35, 0.5, 0.62])
def test_horizon_from_boxes_finds_the_line_through_the_bottoms(horizon):
    from fastdet.video.horizon import horizon_from_boxes

    assert horizon_from_boxes(_perspective_boxes(300, horizon, 720, outliers=45), 720) == pytest.approx(
        horizon, abs=0.01)
    # boxes cut by the frame's bottom edge are left out: a pile of them at the last row moves nothing
    boxes = _perspective_boxes(300, horizon, 720)
    cut = np.c_[np.zeros(200), np.full(200, 500.0), np.linspace(400, 1200, 200), np.full(200, 720.0)]
    assert horizon_from_boxes(np.r_[boxes, cut], 720) == pytest.approx(horizon_from_boxes(boxes, 720))


def test_horizon_from_boxes_says_none_without_a_line():
    from fastdet.video.horizon import MIN_BOXES, horizon_from_boxes

    assert horizon_from_boxes(_perspective_boxes(MIN_BOXES - 1, 0.5, 720), 720) is None
    assert horizon_from_boxes(np.zeros((0, 4)), 720) is None
    rising = _perspective_boxes(100, 0.5, 720, k=-0.5)  # nearer vehicles higher up: no level road
    assert horizon_from_boxes(rising, 720) is None
    same = np.tile([[0.0, 300.0, 50.0, 400.0]], (50, 1))  # one width: no slope
    assert horizon_from_boxes(same, 720) is None
    above = _perspective_boxes(100, -0.2, 720)  # a line meeting width 0 above the frame
    assert horizon_from_boxes(above[above[:, 3] > 0], 720) is None


def test_horizon_from_boxes_samples_a_long_footage():
    from fastdet.video import horizon as hz

    boxes = _perspective_boxes(3 * hz.MAX_BOXES, 0.55, 720, outliers=300)
    assert hz.horizon_from_boxes(boxes, 720) == pytest.approx(0.55, abs=0.01)


def test_horizon_from_boxes_on_the_shared_cameras(data):
    """The ensemble's boxes of two cameras: tmo_seattle1 looks along the road, and its boxes put
    the horizon within 0.03 of where the flow does; hadiya_input8 looks out of a side window,
    where the flow's focus of expansion is 0.2 of the height above the road (docs/geometry.md)
    and the boxes put the horizon at the road's far end, more than 0.15 lower."""
    from fastdet.labels.teacher import read_teacher_clip
    from fastdet.video.horizon import horizon_from_boxes
    from fastdet.video.run import file_horizon

    for name, near in (("tmo_seattle1", True), ("hadiya_input8", False)):
        video = data / "videos" / f"{name}.mp4"
        pics = read_teacher_clip(data / "teacher" / f"{name}.teacher.txt", min_score=0.3, video=video)
        boxes = np.concatenate([p.targets for p in pics if len(p.targets)])
        height = int(cv2.VideoCapture(str(video)).get(cv2.CAP_PROP_FRAME_HEIGHT))
        got, flow = horizon_from_boxes(boxes, height), file_horizon(video)
        assert got is not None and flow is not None
        assert (abs(got - flow) < 0.03) if near else (got - flow > 0.15), (name, got, flow)


def test_a_recorded_camera_horizon_places_the_bands(tmp_path):
    """A main model that records its camera's horizon (``fastdet adapt``) puts the bands there for
    every video, without reading the first seconds ahead; a horizon the config gives wins; a bad
    record is the model's error."""
    from fastdet.errors import ModelError
    from fastdet.model import load_model
    from fastdet.train.blend import offset
    from fastdet.video import VideoDetector, make_detector
    from fastdet.video.detector import HORIZON_KEY, camera_horizon

    model = load_model()
    at = offset(model, 0.0, metadata={HORIZON_KEY: 0.45}).save(tmp_path / "at.npz")
    bad = offset(model, 0.0, metadata={HORIZON_KEY: 1.5}).save(tmp_path / "bad.npz")
    frames = _zoom_frames(24, 150)  # the flow says 150 / 360
    det = make_detector(PipelineConfig(model=str(at)))
    assert camera_horizon(PipelineConfig(), det) == 0.45
    vd = VideoDetector(det, PipelineConfig(model=str(at)))
    assert vd.prime_horizon(frames) == pytest.approx(0.45)  # not the flow's
    vd.update(frames[0])
    assert det.horizon == pytest.approx(0.45)
    given = make_detector(PipelineConfig(model=str(at)))
    VideoDetector(given, PipelineConfig(model=str(at), horizon=0.5)).update(frames[0])
    assert given.horizon == pytest.approx(0.5)
    assert camera_horizon(PipelineConfig(horizon=None), det) is None
    assert camera_horizon(PipelineConfig(), make_detector()) == "auto"  # no record
    assert camera_horizon(PipelineConfig(), object()) == "auto"  # a detector without a model
    with pytest.raises(ModelError, match=HORIZON_KEY):
        camera_horizon(PipelineConfig(), make_detector(PipelineConfig(model=str(bad))))
    # the same from the file's records alone (eval's report, batch's check): no detector built
    from fastdet.video.detector import main_model_records, recorded_horizon

    assert recorded_horizon("auto", main_model_records(PipelineConfig(model=str(at)))) == 0.45
    assert recorded_horizon(0.5, main_model_records(PipelineConfig(model=str(at)))) == 0.5
    assert recorded_horizon("auto", main_model_records(PipelineConfig())) == "auto"
    assert recorded_horizon(None, {HORIZON_KEY: 0.45}) is None
    for record in (1.5, 0.0, True, "0.4"):
        with pytest.raises(ModelError, match=HORIZON_KEY):
            recorded_horizon("auto", {HORIZON_KEY: record})
    with pytest.raises(ModelError):
        main_model_records(PipelineConfig(model=str(tmp_path / "missing.npz")))


def test_a_recorded_horizon_that_leaves_no_room_is_refused_in_its_words(data, tmp_path):
    """A recorded camera horizon with no room for a band below it in this video's frames is one
    line naming the model's record (and how to search elsewhere), not ``--horizon``, which the
    user did not give; the same horizon given as ``--horizon`` is named so."""
    from fastdet.errors import DataError
    from fastdet.io.reader import FrameReader
    from fastdet.model import load_model
    from fastdet.train.blend import offset
    from fastdet.video import make_detector, video_detector_for
    from fastdet.video.detector import HORIZON_KEY

    low = offset(load_model(), 0.0, metadata={HORIZON_KEY: 0.98}).save(tmp_path / "low.npz")
    path = data / "videos" / "test_small1.mp4"
    with FrameReader(path, 0, 10, notify=lambda _n: None) as r:
        with pytest.raises(DataError, match="the camera's horizon the main model records .*leaves no room"):
            video_detector_for(r, make_detector(PipelineConfig(model=str(low))), PipelineConfig(model=str(low)))
    with FrameReader(path, 0, 10, notify=lambda _n: None) as r:
        with pytest.raises(DataError, match="--horizon 0.98 leaves no room"):
            video_detector_for(r, make_detector(), PipelineConfig(horizon=0.98))

"""The main model's operating point set from the video itself (fastdet.video.selfcal)."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from fastdet.config import PipelineConfig, SelfCalibration
from fastdet.detections import MAIN_PART, ONCOMING_PART
from fastdet.video.selfcal import SelfCalStage, calibration_offset
from fastdet.video.state import FrameState


def test_the_offset_is_the_quantile_less_the_level_clipped():
    v = np.linspace(-20.0, 0.0, 1001)  # 10% of them exceed -2.0
    noisy = np.concatenate([v, [np.nan, -np.inf, np.inf]])  # windows not scored are left out
    assert calibration_offset(noisy, SelfCalibration(rate=0.1, level=-8.0, max_shift=10.0)) == pytest.approx(6.0)
    assert calibration_offset(v, SelfCalibration(rate=0.1, level=-8.0, max_shift=3.0)) == pytest.approx(3.0)
    assert calibration_offset(v, SelfCalibration(rate=0.1, level=8.0, max_shift=3.0)) == pytest.approx(-3.0)
    # values scored with an offset of 1 in force: the model's own are 1 higher
    assert calibration_offset(v, SelfCalibration(rate=0.1, level=-8.0, max_shift=10.0), current=1.0) == \
        pytest.approx(7.0)
    assert calibration_offset(v, SelfCalibration(rate=0.3, level=0.0, max_shift=10.0)) == pytest.approx(-6.0)
    with pytest.raises(ValueError, match="no scored window"):
        calibration_offset(np.array([np.nan, -np.inf]), SelfCalibration())


class _TailDetector:
    """Two main bands whose windows score N(mu, sigma) (seeded by the frame's first pixel), less
    the decision offset in force; records which frames it scored."""

    def __init__(self, mu: float, sigma: float, shape: tuple[int, int] = (60, 80)):
        self.mu, self.sigma, self.shape = mu, sigma, shape
        self.decision_offset = 0.0
        self.scored: list[int] = []

    def set_decision_offset(self, delta: float) -> None:
        self.decision_offset = float(delta)

    def geometries(self, frame_shape, part=0):
        return ["a", "b"]

    def band_scores(self, frame, geo, timings=None, part=0):
        seed = int(frame[0, 0, 0])
        if geo == "a":
            self.scored.append(seed)
        rng = np.random.default_rng([seed, ord(geo)])
        return rng.normal(self.mu, self.sigma, self.shape) - self.decision_offset


def _frames(n):
    return [np.full((4, 4, 3), i, np.uint8) for i in range(n)]


def test_a_stream_of_known_tail_gets_its_offset_from_the_frames_the_run_would_full_scan():
    mu, sigma = -6.0, 2.0
    det = _TailDetector(mu, sigma)
    cfg = SelfCalibration(scans=5, rate=0.1, level=-8.0, max_shift=6.0)
    stage = SelfCalStage(det, cfg, every=5)
    frames = _frames(30)
    it = stage.tee(iter(frames[:8]))  # the horizon takes the first 8 frames, the estimate reads on
    assert len(list(it)) == 8
    rest = iter(frames[8:])
    off = stage.prime(rest)
    assert det.scored == [0, 5, 10, 15, 20]  # the full scans of every 5th frame, no other
    assert next(rest) is frames[21]  # read no further than it needed
    expected = mu + 1.2815516 * sigma - cfg.level  # the 90% point of N(mu, sigma), less the level
    assert off == pytest.approx(expected, abs=0.05)
    assert det.decision_offset == off and stage.offset == off and stage.scans == 5
    # clipped to max_shift
    det2 = _TailDetector(mu + 20, sigma)
    assert SelfCalStage(det2, cfg, every=5).prime(iter(frames)) == pytest.approx(6.0)


def test_a_live_stream_takes_its_first_full_scans_and_applies_the_offset_after_them():
    det = _TailDetector(-6.0, 2.0)
    cfg = SelfCalibration(scans=2, rate=0.1, level=-8.0)
    stage = SelfCalStage(det, cfg, every=5)
    rng = np.random.default_rng(0)
    main = [rng.normal(-6.0, 2.0, (50, 50)) for _ in range(2)]
    loud = np.full((50, 50), 100.0)

    def state(dec, full=True):
        s = FrameState(np.zeros((4, 4, 3), np.uint8))
        s.columns = None if full else [[(0, 1)]]
        s.bands = [(MAIN_PART, "a", dec), (ONCOMING_PART, "w", loud)]  # the oncoming model's do not count
        return s

    stage(state(main[0]))
    stage(state(loud, full=False))  # between full scans: not counted
    assert stage.offset is None and det.decision_offset == 0.0
    stage.reset()  # a cut: the estimate goes on
    stage(state(main[1]))
    want = calibration_offset(np.concatenate([m.ravel() for m in main]), cfg)
    assert stage.offset == pytest.approx(want) and det.decision_offset == pytest.approx(want)
    stage(state(loud))  # settled: later frames change nothing
    assert stage.offset == pytest.approx(want)


def test_the_stage_needs_a_detector_that_can_move_its_decision_values():
    from tests.fakes import BrightBoxDetector

    with pytest.raises(TypeError, match="decision values can move"):
        SelfCalStage(BrightBoxDetector(), SelfCalibration())


@functools.lru_cache(maxsize=1)
def _clip_frames(n: int = 12) -> tuple[np.ndarray, ...]:
    from fastdet.data import data_dir
    from fastdet.io.reader import FrameReader

    video = data_dir() / "videos" / "test_video.mp4"
    if not video.is_file():
        pytest.skip(f"{video} not found")
    reader = FrameReader(str(video), 0, n, notify=lambda _n: None)
    try:
        return tuple(np.array(f) for _, f, _ in reader)
    finally:
        reader.close()


def _run(model, config: PipelineConfig, primed: bool = True):
    from dataclasses import replace

    from fastdet.video.detector import make_detector
    from fastdet.video.pipeline import VideoDetector

    frames = _clip_frames()
    vd = VideoDetector(make_detector(replace(config, model=str(model))), config)
    if primed:
        vd.prime_horizon(frames)
    out = []
    offsets = []
    for f in frames:
        d = vd.update(f)
        out.append((d.boxes.copy(), None if d.ids is None else d.ids.copy()))
        st = vd.stage(SelfCalStage)
        offsets.append(st.offset if isinstance(st, SelfCalStage) else None)
    return out, offsets


def test_a_model_shifted_by_a_constant_gets_the_same_boxes_after_self_calibration(data, tmp_path):
    from fastdet.config import DEFAULT_MODEL_PATH
    from fastdet.model import load_model
    from fastdet.train.blend import offset

    model = load_model(DEFAULT_MODEL_PATH)
    shifted = tmp_path / "shifted.npz"
    offset(model, 2.0).save(shifted)  # every decision value 2 lower
    cfg = PipelineConfig(selfcal=SelfCalibration(scans=2))
    a, off_a = _run(DEFAULT_MODEL_PATH, cfg)
    b, off_b = _run(shifted, cfg)
    assert off_a[0] is not None and off_b[0] == pytest.approx(off_a[0] - 2.0, abs=1e-9)
    assert sum(len(x[0]) for x in a) > 0  # test_video has cars in every frame
    for (ba, ia), (bb, ib) in zip(a, b):
        np.testing.assert_array_equal(ba, bb)
        np.testing.assert_array_equal(ia, ib)
    # ... and the same boxes as the model file moved by that offset (blend.offset) without the stage:
    # every threshold on a main-model window moved alike
    moved = tmp_path / "moved.npz"
    offset(model, off_a[0]).save(moved)
    c, _ = _run(moved, PipelineConfig())
    for (ba, _), (bc, _) in zip(a, c):
        np.testing.assert_array_equal(ba, bc)
    # unprimed (a live source): the offset comes with the run's second full scan, not before
    _, live = _run(DEFAULT_MODEL_PATH, cfg, primed=False)
    assert live[0] is None and live[-1] is not None


def test_the_cli_turns_it_on():
    import argparse

    from fastdet.cli._args import add_camera_arguments, pipeline_config

    p = argparse.ArgumentParser()
    add_camera_arguments(p)
    assert pipeline_config(p.parse_args([])).selfcal is None
    on = pipeline_config(p.parse_args(["--self-calibrate"]))
    assert on.selfcal == SelfCalibration() and PipelineConfig.from_dict(on.to_dict()) == on
    assert "selfcal" not in PipelineConfig().to_dict()  # configs written before it keep their digest

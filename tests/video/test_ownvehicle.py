"""The own vehicle's region: fixed, textured and at the border while the scene flows."""
from __future__ import annotations

import functools

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.video.ownvehicle import OwnVehicleConfig, OwnVehicleEstimator, pair_stillness, window_fraction
from tests.reference import ref_box_fraction, ref_pair_stillness

H, W = 360, 640


def _texture(h: int, w: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 6 + 2, w // 6 + 2, 3)).astype(np.uint8)
    return cv2.resize(small, (w + 12, h + 12), interpolation=cv2.INTER_CUBIC)[:h, :w]


#: the tests' estimate: from 1.6 s (40 frames at 25 fps) instead of the default 3 s
SHORT = OwnVehicleConfig(frames_s=1.6)


@functools.lru_cache(maxsize=8)
def _video(n: int = 40, shift: int = 3, dash: bool = True, ahead: bool = True, bars: int = 0,
           noise: int = 2) -> tuple[np.ndarray, ...]:
    """``n`` frames: a textured scene panning ``shift`` px a frame; a fixed textured 'dash' at
    the bottom border (rows 290-360, columns 160-480), a fixed textured 'car ahead' in the
    middle (rows 150-210, columns 280-360), black bars of ``bars`` rows at top and bottom;
    noise of +-``noise`` grey levels (one of 7 noise fields a frame: no two frames of a pair
    0.3 s apart share one). Kept (read-only) for the tests that ask again."""
    rng = np.random.default_rng(1)
    fields = rng.integers(-noise, noise + 1, (7, H, W, 3)).astype(np.int16)
    scene = _texture(H, W + shift * n + 8, 2)
    dash_px = _texture(70, 320, 3)
    car_px = _texture(60, 80, 4)
    out = []
    for i in range(n):
        f = scene[:, shift * i: shift * i + W].copy()
        if dash:
            f[290:360, 160:480] = dash_px
        if ahead:
            f[150:210, 280:360] = car_px
        f = np.clip(f.astype(np.int16) + fields[i % 7], 0, 255).astype(np.uint8)
        if bars:
            f[:bars] = 0
            f[H - bars:] = 0
        f.flags.writeable = False
        out.append(f)
    return tuple(out)


def _region(frames: tuple[np.ndarray, ...], config: OwnVehicleConfig | None = None) -> np.ndarray | None:
    est = OwnVehicleEstimator(config or SHORT, fps=25)
    for f in frames:
        est.update(f)
    assert est.done
    return est.region()


def test_the_dash_at_the_border_is_found_the_car_ahead_is_not():
    region = _region(_video())
    assert region is not None and region.shape == (H, W)
    assert region[300:360, 170:470].mean() > 0.9  # the dash
    assert region[150:210, 280:360].mean() == 0  # still in the picture, but not at the border
    outside = np.ones((H, W), bool)
    outside[280:360, 150:490] = False
    assert region[outside].mean() < 0.01


def test_a_static_camera_masks_nothing_and_letterbox_bars_are_found():
    assert _region(_video(shift=0)) is None  # no flow: no counted pair
    assert _region(_video(dash=False, ahead=False)) is None  # flow, nothing fixed
    region = _region(_video(dash=False, ahead=False, bars=24))
    assert region is not None
    assert region[:20].all() and region[-20:].all()
    assert not region[40:-40].any()
    region = _region(_video(shift=0, dash=False, ahead=False, bars=24))  # bars need no flow
    assert region is not None and region[:20].all() and not region[40:-40].any()


def test_a_region_larger_than_max_area_is_not_the_own_vehicle():
    frames = _video()
    big = _region(frames, OwnVehicleConfig(frames_s=1.6, max_area=0.05))
    assert big is None
    assert _region(frames, OwnVehicleConfig(frames_s=1.6, min_pairs=10_000)) is None  # too few counted pairs


def test_a_cut_pairs_no_frames_across_it_and_a_new_size_restarts():
    frames = _video(n=30)
    est = OwnVehicleEstimator(OwnVehicleConfig(frames_s=10), fps=25)
    for f in frames[:15]:
        est.update(f)
    pairs = est.pairs
    est.cut()
    for f in frames[15:15 + est.gap]:  # the first gap frames after the cut have no partner
        est.update(f)
    assert est.pairs == pairs
    est.update(cv2.resize(frames[0], (320, 180)))
    assert est.pairs == 0 and est.region() is None


@settings(max_examples=40, deadline=None)
@given(st.integers(3, 14), st.integers(3, 14), st.integers(0, 2**31 - 1), st.sampled_from([6.0, 24.0]),
       st.sampled_from([2.0, 8.0]))
def test_pair_stillness_matches_the_reference(h, w, seed, g, t):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 256, (h, w)).astype(np.float32)
    b = np.clip(a + rng.integers(-12, 13, (h, w)), 0, 255).astype(np.float32)
    tex, still = pair_stillness(a, b, g, t)
    rt, rs = ref_pair_stillness(a, b, g, t)
    np.testing.assert_array_equal(tex, rt)
    np.testing.assert_array_equal(still, rs)


def test_pair_stillness_on_real_frames(data):
    from fastdet.io.reader import FrameReader
    r = FrameReader(data / "videos" / "test_video.mp4", 0, 9, notify=lambda _note: None)
    frames = [cv2.cvtColor(cv2.resize(f, (96, 54), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2GRAY)
              .astype(np.float32) for _, f, _ in r]
    r.close()
    tex, still = pair_stillness(frames[0], frames[8], 24.0, 8.0)
    rt, rs = ref_pair_stillness(frames[0], frames[8], 24.0, 8.0)
    np.testing.assert_array_equal(tex, rt)
    np.testing.assert_array_equal(still, rs)
    assert tex.any() and (tex & ~still).any()  # a real drive: texture, and some of it moved


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**31 - 1), st.lists(st.tuples(st.integers(-20, 60), st.integers(-20, 50),
                                                      st.integers(-5, 50), st.integers(-5, 50)),
                                            min_size=1, max_size=6))
def test_window_fraction_matches_the_reference(seed, raw):
    rng = np.random.default_rng(seed)
    region = rng.random((40, 50)) < 0.4
    boxes = np.array([[x, y, x + w, y + h] for x, y, w, h in raw], np.int64)
    got = window_fraction(region, boxes)
    want = [ref_box_fraction(region, b) for b in boxes]
    np.testing.assert_allclose(got, want, atol=1e-12)


# ------------------------------------------------------------------ in the video pipeline

def _pipeline(primed: bool):
    from fastdet.config import PipelineConfig
    from fastdet.detections import Detections
    from fastdet.video.pipeline import VideoDetector
    from tests.fakes import FixedDetector

    # a window mostly on the dash (rows 290-360, columns 160-480) and one on the scene
    dets = Detections(np.array([[200, 280, 264, 344], [40, 60, 104, 124]], np.int32),
                      np.array([2.0, 2.0], np.float32))
    cfg = PipelineConfig(tracker=None, refine=None, horizon=None, own_vehicle=SHORT)
    vd = VideoDetector(FixedDetector(dets), cfg, fps=25)
    frames = _video()
    if primed:
        vd.prime_horizon(frames)
    return vd, frames


def test_the_pipeline_drops_the_windows_on_the_own_vehicle_once_it_is_known():
    from fastdet.video.ownvehicle import OwnVehicleStage

    vd, frames = _pipeline(primed=False)
    assert [s.name for s in vd.stages] == ["detect", "ownvehicle", "heatmap", "split", "plausible"]
    kept = []
    for f in frames:
        vd.update(f)
        kept.append(len(vd.debug.windows))
    stage = vd.stage(OwnVehicleStage)
    assert isinstance(stage, OwnVehicleStage) and stage.region is not None
    assert kept[0] == 2 and kept[-1] == 1  # live: both windows until the estimate is done
    # primed from the file's first frames: the dash window is dropped from the first frame on
    vd, frames = _pipeline(primed=True)
    vd.update(frames[0])
    assert len(vd.debug.windows) == 1
    assert vd.debug.windows.boxes[0].tolist() == [40, 60, 104, 124]
    stage = vd.stage(OwnVehicleStage)
    assert stage.dropped == 1
    vd.reset()  # a cut: the region stays
    vd.update(frames[1])
    assert len(vd.debug.windows) == 1


def test_a_follower_drops_what_its_leader_drops_without_feeding_the_estimate():
    """OwnVehicleFollower (the lanes of fastdet.video.replay): after the leader saw a frame, a
    follower drops from its own windows what the leader's stage would, while the estimate runs
    and once it is done, and never feeds the estimate."""
    from fastdet.detections import Detections
    from fastdet.video.ownvehicle import OwnVehicleFollower, OwnVehicleStage
    from fastdet.video.state import FrameState

    dets = Detections(np.array([[200, 280, 264, 344], [40, 60, 104, 124], [170, 300, 234, 364]], np.int32),
                      np.array([2.0, 2.0, 3.0], np.float32))
    leader, alone = OwnVehicleStage(SHORT, 25), OwnVehicleStage(SHORT, 25)
    follower = OwnVehicleFollower(leader)
    kept = []
    for f in _video():
        leader(FrameState(f))  # the shared estimate, fed once a frame
        got = follower(FrameState(f, windows=dets))
        want = alone(FrameState(f, windows=dets))
        assert got.windows.boxes.tolist() == want.windows.boxes.tolist()
        kept.append(len(got.windows))
        assert leader.estimator.frames == alone.estimator.frames  # the follower fed nothing
    assert kept[0] == 3 and kept[-1] == 1 and follower.dropped == alone.dropped > 0


def test_the_cli_turns_the_stages_on_and_off(tmp_path):
    import argparse

    from fastdet.cli._args import add_camera_arguments, pipeline_config
    from fastdet.config import NeighbourSplit, OwnVehicleConfig, PipelineConfig

    p = argparse.ArgumentParser()
    add_camera_arguments(p)
    on = pipeline_config(p.parse_args(["--own-vehicle", "--split-neighbours"]))
    assert on.own_vehicle == OwnVehicleConfig() and on.split == NeighbourSplit()
    default = pipeline_config(p.parse_args([]))
    assert default.own_vehicle == OwnVehicleConfig() and default.split == NeighbourSplit()
    assert default == on and default.to_dict() == PipelineConfig().to_dict()
    assert PipelineConfig.from_dict(on.to_dict()) == on
    no_own = pipeline_config(p.parse_args(["--no-own-vehicle"]))
    assert no_own.own_vehicle is None and PipelineConfig.from_dict(no_own.to_dict()) == no_own
    off = pipeline_config(p.parse_args(["--no-split-neighbours"]))
    assert off.split is None and PipelineConfig.from_dict(off.to_dict()) == off
    with pytest.raises(SystemExit):
        p.parse_args(["--split-neighbours", "--no-split-neighbours"])

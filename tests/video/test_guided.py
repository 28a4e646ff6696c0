"""Tracking-guided search (fastdet.video.guided): when the planner scans in full, which window
columns it picks in between, and that VideoDetector with it finds what the full search finds."""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import GuidedSearch, PipelineConfig
from fastdet.detect import Detector
from fastdet.detections import Detections
from fastdet.eval.metrics import evaluate
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import FrameReader
from fastdet.video import VideoDetector, prime_horizon_from_file
from fastdet.video.guided import SearchPlanner, merge_spans
from fastdet.video.stages import PlanStage

SHAPE = (720, 1280)


@pytest.fixture(scope="module")
def det():
    d = Detector()
    d.warmup()
    return d


def _windows(boxes, scale):
    b = np.asarray(boxes, np.int32).reshape(-1, 4)
    return Detections(b, np.ones(len(b), np.float32), scale=np.full(len(b), scale, np.float32),
                      part=np.zeros(len(b), np.int8))


def _plan(p, det):
    cfg = det.config
    return p.plan(det.geometries(SHAPE), cfg.win_w, cfg.pixels_per_cell, SHAPE)


def test_merge_spans():
    assert merge_spans([(5, 9), (0, 2), (3, 4), (20, 22), (8, 12), (7, 7)], gap=1) == [(0, 12), (20, 22)]
    assert merge_spans([(0, 2), (10, 12)], gap=8) == [(0, 12)]
    assert merge_spans([]) == []


def test_full_scans(det):
    p = SearchPlanner(GuidedSearch(every=4))
    plans = []
    for i in range(9):
        plans.append(_plan(p, det))
        p.observe(Detections.empty(), [], lost=i == 5)
    # the first frame, every 4th frame after a full scan, and the frame after a lost track
    assert [pl is None for pl in plans] == [True, False, False, False, True, False, True, False, False]
    p.reset()
    assert _plan(p, det) is None
    assert p.plan(det.geometries(SHAPE), 64, 8, (720, 1281)) is None  # another frame size
    assert SearchPlanner(GuidedSearch(every=1)).plan(det.geometries(SHAPE), 64, 8, SHAPE) is None


def test_columns_between_full_scans(det):
    geos = det.geometries(SHAPE)
    g = GuidedSearch(every=4, margin=0.5)
    p = SearchPlanner(g)
    assert _plan(p, det) is None
    one = next(geo for geo in geos if geo.band.scale == 1.0)
    # a positive window of the scale-1 band at x 600..664, and a 100x80 track at x 900..1000
    p.observe(_windows([[600, 420, 664, 484]], 1.0), [(np.array([900., 420, 1000, 500]),) * 2 + (0,)], False)
    plan = _plan(p, det)
    for geo, spans in zip(geos, plan, strict=True):
        scored = np.zeros(geo.nx, bool)
        for j0, j1 in spans:
            scored[j0:j1] = True
        px = geo.step * 8 * geo.band.scale
        left = geo.x0 + np.arange(geo.nx) * px
        right = left + 64 * geo.band.scale
        # the strip: frame 1 of 4 -> x 320..640 in every band
        assert scored[(right > 320) & (left < 640)].all()
        if geo is one:  # near the positive window: 600 - 32 .. 664 + 32
            assert scored[(right > 568) & (left < 696)].all()
        near_track = (right > 850) & (left < 1050)
        if 0.4 * 80 <= 64 * geo.band.scale <= 2.0 * 80:
            assert scored[near_track].all()
        far = (left > 1100) | (right < 300)
        assert not scored[far].any()


def _run(clip, guided, data):
    path = str(data / "videos" / clip)
    reader = FrameReader(path)
    vd = VideoDetector(config=PipelineConfig(guided=guided), fps=reader.fps)
    prime_horizon_from_file(vd, path)
    out = [(fno, vd.update(frame)) for fno, frame, _ in reader]
    return vd, out, path


def test_guided_video_finds_what_the_full_search_finds(data):
    clip = "test_video.mp4"
    vd, guided, path = _run(clip, GuidedSearch(), data)
    assert 0 < vd.stage(PlanStage).planner.full_scans < len(guided)
    _, full, _ = _run(clip, None, data)
    gt = read_gt(str(data / "annotations" / "test_video.gt.txt"))
    a = evaluate(gt, Detections.from_frames(guided, source=path)).to_dict()
    b = evaluate(gt, Detections.from_frames(full, source=path)).to_dict()
    for k in ("f1", "ap", "idf1"):
        assert abs(a[k] - b[k]) <= 0.01, (k, a[k], b[k])


def test_full_search_flag(data, capsys):
    from fastdet.cli._args import pipeline_config
    from fastdet.cli.main import build_parser, main

    for cmd in (["video", "in.mp4", "--boxes", "b.txt"], ["eval", "--gt", "g.txt", "--video", "v.mp4"], ["bench"]):
        assert pipeline_config(build_parser().parse_args([*cmd, "--full-search"])).guided is None
        assert pipeline_config(build_parser().parse_args(cmd)).guided == GuidedSearch()
    gt, video = data / "annotations" / "test_video.gt.txt", data / "videos" / "test_video.mp4"
    res = []
    for flag in ([], ["--full-search"]):
        assert main(["eval", "--gt", str(gt), "--video", str(video), "--json", *flag]) == 0
        res.append(json.loads(capsys.readouterr().out.strip().splitlines()[-1]))
    for k in ("f1", "ap", "idf1"):
        assert abs(res[0][k] - res[1][k]) <= 0.01


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(0, 40))
def test_planner_picks_the_windows_of_a_band_as_isclose(seed, n):
    """The planner keeps each frame's windows grouped by scale and matches a band's scale
    once per pair (cached): the same windows as ``np.isclose(windows.scale, s)``."""
    from fastdet.video.guided import SearchPlanner

    rng = np.random.default_rng(seed)
    bands = [0.5, 0.75, 1.0, 1.5, 1.0 + 1e-7, 2.0]
    scale = rng.choice(bands + [np.nan, 0.7500001, 1.25], n).astype(np.float32)
    x1 = rng.integers(-50, 1200, n)
    boxes = np.stack([x1, rng.integers(0, 700, n), x1 + rng.integers(1, 200, n), rng.integers(0, 700, n)], 1)
    wins = Detections(boxes.astype(np.int32), rng.random(n).astype(np.float32), scale=scale)
    p = SearchPlanner()
    grouped = p._group(wins)
    for s in bands + [0.75000003]:
        got = sorted(x for u, xs in grouped.items() if p._close(u, s) for x in xs)
        want = sorted(map(tuple, wins.boxes[np.isclose(wins.scale, s)][:, [0, 2]].tolist()))
        assert got == want

"""The side-view component in the video pipeline: PipelineConfig.side, make_detector, the
components' own heat map (ComponentStage) and the guided search over their bands."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from fastdet.config import SIDE_MODEL_PATH, PipelineConfig
from fastdet.detections import FIRST_COMPONENT_PART, MAIN_PART, Detections
from fastdet.video import VideoDetector, make_detector
from fastdet.video.guided import SearchPlanner
from tests.fakes import FixedDetector


def test_config_side_and_make_detector(tmp_path):
    assert PipelineConfig().side is False
    det = make_detector(PipelineConfig(side=True, oncoming=False))
    assert det.parts == [MAIN_PART, FIRST_COMPONENT_PART] and len(det.components) == 1
    assert (det.components[0].config.win_w, det.components[0].config.win_h) == (64, 32)
    assert PipelineConfig(side=SIDE_MODEL_PATH).side == str(SIDE_MODEL_PATH)
    assert PipelineConfig(side=True).without("side").side is False
    with pytest.raises(TypeError, match="side"):
        PipelineConfig(side=None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="side_heat"):
        PipelineConfig(side_heat="hot")  # type: ignore[arg-type]
    assert len(make_detector(PipelineConfig(oncoming=False)).parts) == 1


class _ComponentFake(FixedDetector):
    components = ["a component"]


def _frame():
    return np.zeros((720, 1280, 3), np.uint8)


def test_component_windows_get_their_own_heat_map_and_join_where_main_found_nothing():
    car = [[400, 400, 528, 528]] * 4  # main-model windows on one car, confident
    side = [[800, 450, 1056, 578]] * 4  # component windows elsewhere
    over = [[380, 420, 636, 548]] * 4  # component windows over the main car
    boxes = np.array(car + side + over)
    part = [MAIN_PART] * 4 + [FIRST_COMPONENT_PART] * 8
    dets = Detections(boxes, np.full(len(boxes), 3.0), scale=np.full(len(boxes), 2.0), part=part)
    cfg = PipelineConfig(tracker=None, refine=None, horizon=None, oncoming=False, split=None)
    vd = VideoDetector(_ComponentFake(dets), cfg)
    assert [s.name for s in vd.stages] == ["detect", "ownvehicle", "heatmap", "components", "plausible"]
    out = vd.update(_frame())
    main_only = VideoDetector(FixedDetector(dets[np.array(part) == MAIN_PART]), cfg).update(_frame())
    assert len(main_only) == 1
    # the main car's box is the main heat map's alone (the wide windows over it do not stretch it),
    # the component's box elsewhere is added
    assert len(out) == 2
    np.testing.assert_array_equal(out.boxes[0], main_only.boxes[0])
    x1, y1, x2, y2 = out.boxes[1]
    assert x1 >= 780 and x2 <= 1076 and x2 - x1 > y2 - y1
    assert "components" in vd.timings


def test_pipeline_with_the_side_component_plans_its_bands_and_finds_its_windows(test_images):
    frame = cv2.imread(str(test_images[0]))
    cfg = PipelineConfig(side=True)
    vd = VideoDetector(make_detector(cfg), cfg)
    assert "components" in [s.name for s in vd.stages]
    seen = []
    for _ in range(3):
        vd.update(frame)
        seen.append(vd.debug.windows)
    det = vd.detector
    plan = next(s for s in vd.stages if s.name == "plan")
    state = type("S", (), {"shape": frame.shape[:2]})()
    plan(state)  # a frame between full scans: a column plan for the main and the side bands
    assert state.columns is not None and len(state.columns) == len(det.main_geometries(frame.shape[:2]))
    assert any((w.part == FIRST_COMPONENT_PART).any() for w in seen)


def test_plan_takes_one_width_per_band():
    from fastdet.config import GuidedSearch

    p = SearchPlanner(GuidedSearch())
    with pytest.raises(ValueError, match="widths"):
        p.plan([object(), object()], [64], 8, (720, 1280))  # type: ignore[list-item]


class _TwoComponentFake(FixedDetector):
    components = ["side", "small"]


def test_small_component_gets_a_heat_map_of_its_own_and_its_threshold():
    from dataclasses import replace

    from fastdet.config import HeatConfig
    from fastdet.video.detector import small_part

    side = [[800, 450, 1056, 578]] * 4  # side-component windows
    small = [[300, 400, 348, 448]] * 3  # small-component windows on a distant car, probability 0.75: heat 2.5 each
    boxes = np.array(side + small)
    part = [FIRST_COMPONENT_PART] * 4 + [FIRST_COMPONENT_PART + 1] * 3
    scores = np.r_[np.full(4, 0.99), np.full(3, 0.75)]
    dets = Detections(boxes, scores.astype(np.float32), scale=np.full(len(boxes), 1.5), part=part)
    det = _TwoComponentFake(dets)
    det.score_kind = "probability"
    cfg = PipelineConfig(tracker=None, refine=None, horizon=None, oncoming=False, small="unused.npz", side=True,
                         split=None)
    assert small_part(cfg, det) == FIRST_COMPONENT_PART + 1
    assert small_part(cfg.without("small"), det) is None
    vd = VideoDetector(det, cfg)
    assert [s.name for s in vd.stages] == ["detect", "ownvehicle", "heatmap", "components", "small", "plausible"]
    stages = {s.name: s for s in vd.stages}
    assert stages["components"].parts == (FIRST_COMPONENT_PART,)
    assert stages["small"].parts == (FIRST_COMPONENT_PART + 1,)
    out = vd.update(_frame())
    # 3 x 2.5 = 7.5 over the small car's pixels: above the default threshold 4, a box there
    assert len(out) == 2 and any(b[0] >= 296 and b[2] <= 352 for b in out.boxes)
    assert "small" in vd.timings
    # its own threshold: above 7.5 the small car's windows no longer make a box; the side one's stays
    strict = replace(cfg, small_heat=HeatConfig(threshold=8.0))
    out = VideoDetector(det, strict).update(_frame())
    assert len(out) == 1 and out.boxes[0][0] >= 780
    # without the small component in the config, every component's windows share one heat map
    vd = VideoDetector(det, cfg.without("small"))
    assert [s.name for s in vd.stages] == ["detect", "ownvehicle", "heatmap", "components", "plausible"]


def test_make_detector_puts_the_small_component_last(tmp_path):
    from fastdet.config import SMALL_MODEL_PATH, SMALL_SEARCH
    from fastdet.video.detector import small_part

    det = make_detector(PipelineConfig(small=True, side=True, oncoming=False))
    assert det.parts == [MAIN_PART, FIRST_COMPONENT_PART, FIRST_COMPONENT_PART + 1]
    assert (det.components[1].config.win_w, det.components[1].config.win_h) == (32, 32)
    assert det._scorer_of[FIRST_COMPONENT_PART + 1].search == SMALL_SEARCH
    assert small_part(PipelineConfig(small=True), det) == FIRST_COMPONENT_PART + 1
    alone = make_detector(PipelineConfig(small=SMALL_MODEL_PATH, oncoming=False))
    assert alone.parts == [MAIN_PART, FIRST_COMPONENT_PART] and alone.components[0].config.win_w == 32

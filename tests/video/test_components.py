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
    cfg = PipelineConfig(tracker=None, refine=None, horizon=None, oncoming=False)
    vd = VideoDetector(_ComponentFake(dets), cfg)
    assert [s.name for s in vd.stages] == ["detect", "heatmap", "components", "plausible"]
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

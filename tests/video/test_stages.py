"""VideoDetector.update as a fixed sequence of stages (fastdet.video.stages): which stages a
config and a detector give, in which order, their timings and the FrameDebug record."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.config import PipelineConfig
from fastdet.detections import Detections
from fastdet.video import VideoDetector, make_detector
from fastdet.video.stages import FrameState, Stage
from tests.fakes import SquareDetector


def frame() -> np.ndarray:
    f = np.zeros((360, 640, 3), np.uint8)
    f[100:160, 200:280] = 255
    return f


def names(vd: VideoDetector) -> list[str]:
    return [s.name for s in vd.stages]


def test_the_default_pipeline_runs_every_stage_in_order():
    vd = VideoDetector(make_detector())
    assert names(vd) == ["horizon", "plan", "motion", "detect", "motion", "ownvehicle", "heatmap", "split", "fusion",
                         "weak", "track", "observe", "refine", "plausible"]
    off = VideoDetector(make_detector(), PipelineConfig(tracker=None, refine=None, horizon=None, plausible=None,
                                                        split=None))
    # no tracker: the full search
    assert names(off) == ["motion", "detect", "motion", "ownvehicle", "heatmap", "fusion"]


def test_a_detector_without_abilities_gets_no_horizon_or_plan_stage():
    vd = VideoDetector(SquareDetector(), PipelineConfig(refine=None, plausible=None))
    assert names(vd) == ["detect", "ownvehicle", "heatmap", "split", "weak", "track"]
    from fastdet.config import TrackerConfig

    vd = VideoDetector(SquareDetector(), PipelineConfig(refine=None, tracker=TrackerConfig(output="filtered")))
    assert names(vd)[-2:] == ["clip", "plausible"]


def test_timings_name_every_stage_and_its_parts():
    vd = VideoDetector(SquareDetector(), PipelineConfig(refine=None))
    vd.update(frame())
    assert set(vd.timings) == {"detect", "resize_colour", "hog", "score", "ownvehicle", "heatmap", "heat", "label",
                               "split", "weak", "track", "plausible"}
    assert all(v >= 0 for v in vd.timings.values())


def test_a_stage_added_to_the_list_runs_on_the_state():
    class DropAll(Stage):
        name = "drop"

        def __call__(self, s: FrameState) -> FrameState:
            s.out = Detections.empty()
            return s

    vd = VideoDetector(SquareDetector(), PipelineConfig(refine=None, tracker=None,
                                                        heat=PipelineConfig().heat.single_frame(1.0)))
    assert len(vd.update(frame())) == 1
    vd.stages.append(DropAll())
    assert len(vd.update(frame())) == 0 and "drop" in vd.timings


def test_video_detector_refuses_what_is_not_a_config_or_detector():
    with pytest.raises(TypeError, match="PipelineConfig"):
        VideoDetector(SquareDetector(), PipelineConfig().heat)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="WindowDetector"):
        VideoDetector(object())  # type: ignore[arg-type]

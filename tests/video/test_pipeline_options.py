"""The video pipeline's per-run options: the learned box refinement (on by default,
``PipelineConfig(refine=None)`` / ``--no-refine``) and the side of the road traffic drives on
(``PipelineConfig(traffic=...)`` / ``--traffic``), through the API, the CLI and batch settings."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fastdet.cli import eval as eval_cmd
from fastdet.cli.main import build_parser
from fastdet.config import PipelineConfig
from fastdet.errors import FastdetError
from fastdet.io.reader import FrameReader
from fastdet.video import VideoDetector, make_detector
from fastdet.video.refine import BoxRegressor, RefineConfig, load_regressor, refine


def test_refinement_is_on_by_default_and_can_be_turned_off():
    assert isinstance(VideoDetector().refiner, BoxRegressor)
    assert VideoDetector().config.refine == RefineConfig()
    off = VideoDetector(config=PipelineConfig(refine=None))
    assert off.refiner is None and off.config.refine is None
    two = VideoDetector(config=PipelineConfig(refine=RefineConfig(iterations=2)))
    assert two.config.refine.iterations == 2
    zero = BoxRegressor.zero()
    assert VideoDetector(refiner=zero).refiner is zero
    with pytest.raises(TypeError, match="refine"):
        PipelineConfig(refine="yes")  # type: ignore[arg-type]


def test_refined_boxes_are_the_unrefined_run_refined(data: Path):
    """Refinement only moves the returned boxes: a run with it equals a run without it whose
    boxes are refined afterwards (same ids, same count), and it is timed."""
    reader = FrameReader(data / "videos" / "test_video.mp4", 0, 12)
    det = make_detector()
    on = VideoDetector(det, PipelineConfig(horizon=None))
    off = VideoDetector(det, PipelineConfig(horizon=None, refine=None))
    reg = load_regressor()
    moved = 0
    try:
        for _, frame, _ in reader:
            a, b = on.update(frame), off.update(frame)
            expect = refine(frame, b, reg, RefineConfig())
            np.testing.assert_array_equal(a.boxes, expect.boxes)
            np.testing.assert_array_equal(a.ids, b.ids)
            np.testing.assert_array_equal(on.debug.boxes.boxes, off.debug.boxes.boxes)
            assert "refine" in on.timings and "refine" not in off.timings
            moved += int(np.any(a.boxes != b.boxes))
    finally:
        reader.close()
    assert moved > 0  # the regressor does move the boxes of real cars


def test_cli_options_parse_and_eval_refuses_them_without_video(tmp_path: Path):
    p = build_parser()
    a = p.parse_args(["video", "x.mp4", "--traffic", "left", "--no-refine"])
    assert a.traffic == "left" and a.no_refine
    a = p.parse_args(["video", "x.mp4"])
    assert a.traffic == "right" and not a.no_refine
    with pytest.raises(SystemExit):
        p.parse_args(["video", "x.mp4", "--traffic", "middle"])
    gt = tmp_path / "gt.txt"
    gt.write_text("1,1,10,10,50,50,1,1,1\n")
    for extra in (["--no-refine"], ["--traffic", "left"]):
        args = p.parse_args(["eval", "--gt", str(gt), "--pred", str(gt), *extra])
        with pytest.raises(FastdetError, match="only apply with --video"):
            eval_cmd.run(args)


def test_batch_settings_record_refinement_and_traffic():
    pytest.importorskip("distributed")
    from fastdet.batch.settings import Settings

    base = Settings.create()
    assert base.pipeline.refine and base.refine_sha256 and base.pipeline.traffic == "right"
    off = Settings.create(PipelineConfig(refine=None))
    left = Settings.create(PipelineConfig(traffic="left"))
    assert len({base.digest(), off.digest(), left.digest()}) == 3
    assert base.record()["refine_sha256"] == base.refine_sha256 and off.record()["refine_sha256"] == ""
    assert off.record()["refine"] is None and base.record()["refine"] == RefineConfig().to_dict()
    with pytest.raises(ValueError, match="traffic"):
        Settings.create(PipelineConfig(traffic="middle"))  # type: ignore[arg-type]

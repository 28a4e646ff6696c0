"""fastdet/config/heat.py: HeatConfig's checks, its one-image variant, round trip and box sizes
scaled to the frame (the heat map itself: tests/video/test_heatmap.py)."""
from __future__ import annotations

import pytest

from fastdet.config import HeatConfig


@pytest.mark.parametrize("kw", [
    dict(n_frames=0), dict(decay=0.0), dict(decay=1.5), dict(threshold=-1), dict(threshold=float("nan")),
    dict(score_lo=1.0), dict(score_lo=2.0, score_hi=1.0), dict(w_max=0.5), dict(cell=0), dict(min_width=-1),
    dict(max_aspect=0), dict(single_frame_threshold=-0.5), dict(extent=-0.1), dict(extent=1.5),
    dict(split_gap=-0.5), dict(split_gap=float("inf")), dict(split_gap=0.5, box_mode="mean"),
])
def test_heatconfig_validation(kw):
    with pytest.raises(ValueError):
        HeatConfig(**kw)


def test_heatconfig_single_frame_and_round_trip():
    cfg = HeatConfig(n_frames=6, threshold=1.0, single_frame_threshold=3.0)
    sf = cfg.single_frame()
    assert sf.n_frames == 1 and sf.threshold == 3.0 and sf.cell == cfg.cell
    assert cfg.single_frame(5.0).threshold == 5.0
    assert HeatConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ValueError):
        HeatConfig.from_dict({"bogus": 1})


def test_heat_for_frame_scales_box_sizes():
    cfg = HeatConfig()  # min 40 x 20 px at 720 rows
    assert (cfg.for_frame(720).min_width, cfg.for_frame(720).min_height) == (40, 20)
    assert (cfg.for_frame(360).min_width, cfg.for_frame(360).min_height) == (20, 10)
    assert (cfg.for_frame(1080).min_width, cfg.for_frame(1080).min_height) == (60, 30)
    assert cfg.for_frame(360).reference_rows is None
    assert cfg.for_frame(360).for_frame(100) == cfg.for_frame(360)  # already in pixels
    pixels = HeatConfig(reference_rows=None)
    assert pixels.for_frame(360) == pixels
    with pytest.raises(ValueError):
        HeatConfig(reference_rows=0)


def test_heat_frames_and_cell_are_bounded():
    """issue 34, item 12: ``--heat-frames 100000000`` built a list of 10**8 weights (4.2 GB)."""
    import time

    from fastdet.config.heat import MAX_HEAT_CELL, MAX_HEAT_FRAMES
    from fastdet.video.heatmap import HeatMap
    for kw in ({"n_frames": 100_000_000}, {"n_frames": 3 * 10**9}, {"n_frames": MAX_HEAT_FRAMES + 1},
               {"cell": MAX_HEAT_CELL + 1}):
        with pytest.raises(ValueError, match="at most|in 1\\.\\."):
            HeatConfig(**kw)
    t0 = time.perf_counter()
    HeatMap((720, 1280), HeatConfig(n_frames=MAX_HEAT_FRAMES))
    assert time.perf_counter() - t0 < 1


def test_cli_heat_frames_out_of_domain_is_one_line():
    import argparse

    from fastdet.cli._args import pipeline_config
    from fastdet.errors import FastdetError
    with pytest.raises(FastdetError, match="heat map: n_frames must be at most"):
        pipeline_config(argparse.Namespace(heat_frames=100_000_000))

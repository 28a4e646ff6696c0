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

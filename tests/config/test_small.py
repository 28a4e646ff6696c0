"""The small-vehicle component's configuration: its features, its search about the horizon (no
upsampling of a 1280x720 frame, INTER_AREA shrinking), its heat map, and PipelineConfig.small."""
from __future__ import annotations

import pytest

from fastdet.config import (
    REFERENCE_HORIZON,
    REFERENCE_SHAPE,
    SMALL_FEATURES,
    SMALL_HEAT,
    SMALL_MODEL_PATH,
    SMALL_SEARCH,
    PipelineConfig,
    SearchConfig,
)
from fastdet.config.small import SMALL_SCALES, SMALL_WINDOW, small_search


def test_features_are_a_coarse_square_template():
    assert (SMALL_FEATURES.win_w, SMALL_FEATURES.win_h) == (SMALL_WINDOW, SMALL_WINDOW) == (32, 32)
    assert SMALL_FEATURES.pixels_per_cell == 8 and (SMALL_FEATURES.cells_x, SMALL_FEATURES.cells_y) == (4, 4)
    assert SMALL_FEATURES.spatial_shape == (16, 16)


def test_search_shrinks_every_band_about_the_horizon():
    s = small_search()
    assert s == SMALL_SEARCH and s.shrink == "area" and s.cells_per_step == 1
    assert tuple(b.scale for b in s.bands) == SMALL_SCALES
    hz = REFERENCE_HORIZON * REFERENCE_SHAPE[0]
    for b in s.bands:
        assert b.scale >= 1.0  # 1280x720: never upsampled
        w = SMALL_WINDOW * b.scale
        assert b.y_start < hz - 0.5 * w and b.y_stop > hz + w  # vehicles w wide stand about there
        assert b.y_stop - b.y_start < 5 * w  # a band about the horizon, not the whole frame
        assert b.x_start is None and b.x_stop is None  # the whole width
    # the bands move with the horizon as every search's do
    moved = s.for_frame(REFERENCE_SHAPE)
    assert moved.bands == s.bands
    up = SearchConfig(bands=s.bands, cells_per_step=1, horizon=0.45, shrink="area").for_frame(REFERENCE_SHAPE)
    assert all(a.y_start < b.y_start for a, b in zip(up.bands, s.bands))
    assert up.shrink == "area"


def test_shrink_is_checked_and_round_trips():
    with pytest.raises(ValueError, match="shrink"):
        SearchConfig(shrink="cubic")  # type: ignore[arg-type]
    assert SearchConfig.from_dict(SMALL_SEARCH.to_dict()) == SMALL_SEARCH
    assert SearchConfig().shrink == "linear"


def test_pipeline_config_small():
    c = PipelineConfig()
    assert c.small is False and c.small_search == SMALL_SEARCH and c.small_heat == SMALL_HEAT
    assert PipelineConfig(small=SMALL_MODEL_PATH).small == str(SMALL_MODEL_PATH)
    on = PipelineConfig(small=True)
    assert on.without("small").small is False and on.without("refine").small is True
    assert PipelineConfig.from_dict(on.to_dict()) == on
    with pytest.raises(TypeError, match="small"):
        PipelineConfig(small=None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="small_search"):
        PipelineConfig(small_search="near")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="small_heat"):
        PipelineConfig(small_heat="hot")  # type: ignore[arg-type]


@pytest.mark.parametrize("cmd", [["video", "in.mp4", "--boxes", "b.txt"], ["eval", "--all"], ["bench"],
                                 ["batch", "in.mp4", "--out", "o"]])
def test_the_cli_small_flags(cmd):
    from fastdet.cli._args import pipeline_config
    from fastdet.cli.main import build_parser

    parse = build_parser().parse_args
    assert pipeline_config(parse(cmd)).small is False
    assert pipeline_config(parse([*cmd, "--small"])).small is True
    assert pipeline_config(parse([*cmd, "--small-model", "s.npz"])).small.endswith("s.npz")
    with pytest.raises(SystemExit):
        parse([*cmd, "--small", "--small-model", "s.npz"])

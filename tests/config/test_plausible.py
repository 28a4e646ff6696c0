"""fastdet.config.PlausibleConfig: its defaults, its checks and its place in PipelineConfig."""
from __future__ import annotations

import json

import pytest

from fastdet.config import PipelineConfig, PlausibleConfig


def test_defaults_drop_duplicates_and_round_trip():
    c = PlausibleConfig()
    assert c.max_iou == 0.5
    assert PipelineConfig().plausible == c
    for cfg in (PipelineConfig(), PipelineConfig(plausible=None),
                PipelineConfig(plausible=PlausibleConfig(max_iou=None))):
        back = PipelineConfig.from_dict(json.loads(json.dumps(cfg.to_dict())))
        assert back == cfg and back.digest() == cfg.digest()
    assert PipelineConfig(plausible=None).digest() != PipelineConfig().digest()
    # the deleted perspective test: a dict holding its off values loads, one with it on is refused
    assert PlausibleConfig.from_dict({"max_iou": 0.5, "perspective": False, "min_ratio": 0.45, "max_ratio": 12.0,
                                      "slack": 0.05}) == c
    with pytest.raises(ValueError, match="deleted"):
        PlausibleConfig.from_dict({"perspective": True})


@pytest.mark.parametrize("kw", [{"max_iou": 1.5}, {"max_iou": -0.1}])
def test_plausible_config_refuses(kw):
    with pytest.raises(ValueError):
        PlausibleConfig(**kw)
    with pytest.raises(TypeError, match="plausible must be a PlausibleConfig or None"):
        PipelineConfig(plausible=0.5)  # type: ignore[arg-type]


def test_every_command_has_the_default_stage():
    from fastdet.cli._args import pipeline_config
    from fastdet.cli.main import build_parser

    parse = build_parser().parse_args
    for cmd in (["video", "in.mp4", "--boxes", "b.txt"], ["eval", "--all"], ["bench"],
                ["batch", "in.mp4", "--out", "o"]):
        assert pipeline_config(parse(cmd)).plausible == PlausibleConfig()

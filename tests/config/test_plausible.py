"""fastdet.config.PlausibleConfig: its defaults, its checks and its place in PipelineConfig."""
from __future__ import annotations

import json

import pytest

from fastdet.config import PipelineConfig, PlausibleConfig


def test_defaults_drop_duplicates_only_and_round_trip():
    c = PlausibleConfig()
    assert c.max_iou == 0.5 and c.perspective is False
    assert PipelineConfig().plausible == c
    for cfg in (PipelineConfig(), PipelineConfig(plausible=None), PipelineConfig(plausible=PlausibleConfig(
            max_iou=None, perspective=True, min_ratio=0.3, max_ratio=20.0, slack=0.1))):
        back = PipelineConfig.from_dict(json.loads(json.dumps(cfg.to_dict())))
        assert back == cfg and back.digest() == cfg.digest()
    assert PipelineConfig(plausible=None).digest() != PipelineConfig().digest()


@pytest.mark.parametrize("kw, err", [({"max_iou": 1.5}, ValueError), ({"max_iou": -0.1}, ValueError),
                                     ({"perspective": 1}, TypeError), ({"min_ratio": 0}, ValueError),
                                     ({"max_ratio": float("inf")}, ValueError),
                                     ({"min_ratio": 2.0, "max_ratio": 1.0}, ValueError), ({"slack": 1.0}, ValueError),
                                     ({"slack": -0.01}, ValueError)])
def test_plausible_config_refuses(kw, err):
    with pytest.raises(err):
        PlausibleConfig(**kw)
    with pytest.raises(TypeError, match="plausible must be a PlausibleConfig or None"):
        PipelineConfig(plausible=0.5)  # type: ignore[arg-type]


def test_the_cli_turns_the_perspective_test_on():
    from fastdet.cli._args import pipeline_config
    from fastdet.cli.main import build_parser

    parse = build_parser().parse_args
    for cmd in (["video", "in.mp4", "--boxes", "b.txt"], ["eval", "--all"], ["bench"],
                ["batch", "in.mp4", "--out", "o"]):
        assert pipeline_config(parse(cmd)).plausible == PlausibleConfig()
        assert pipeline_config(parse([*cmd, "--perspective-filter"])).plausible == PlausibleConfig(perspective=True)

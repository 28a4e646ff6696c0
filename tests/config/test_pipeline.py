"""fastdet.config: one to_dict / from_dict / digest for every config, PipelineConfig's checks,
the CLI's one builder of it (the batch settings made of it: tests/config/test_batch.py)."""
from __future__ import annotations

import json
from dataclasses import replace

import pytest

from fastdet.config import (
    FeatureConfig,
    GuidedSearch,
    HeatConfig,
    JitterConfig,
    MotionGate,
    PipelineConfig,
    RefineConfig,
    SearchBand,
    SearchConfig,
    TrackerConfig,
    oncoming_search,
)

CONFIGS = [FeatureConfig(), FeatureConfig(window_height=24, hog_channels=(0,)), SearchConfig(),
           SearchConfig(horizon=0.5, reference_shape=None), oncoming_search("left"),
           HeatConfig(score_lo=0.1, score_hi=2),
           MotionGate(30.0), TrackerConfig(output="filtered"), GuidedSearch(scales=(0.5, 1.5)),
           RefineConfig(parts=(0, 1)), JitterConfig(), PipelineConfig(),
           PipelineConfig(oncoming=False, tracker=None, guided=None, refine=None, horizon=None, traffic="both"),
           PipelineConfig(model="a.npz", oncoming="b.npz", horizon=0.4, heat=HeatConfig(n_frames=3))]


@pytest.mark.parametrize("config", CONFIGS, ids=lambda c: type(c).__name__)
def test_every_config_round_trips_through_json(config):
    d = json.loads(json.dumps(config.to_dict()))
    back = type(config).from_dict(d)
    assert back == config and hash(back) == hash(config)
    assert back.digest() == config.digest()


def test_digest_is_stable_and_tells_configs_apart():
    base = PipelineConfig()
    assert base.digest() == PipelineConfig().digest() and len(base.digest()) == 16
    others = [PipelineConfig(traffic="left"), PipelineConfig(tracker=None),
              PipelineConfig(heat=HeatConfig(threshold=5)),
              PipelineConfig(search=replace(SearchConfig(), bands=(SearchBand(1.0, 400, 500),)))]
    assert len({base.digest(), *(c.digest() for c in others)}) == 1 + len(others)


def test_from_dict_refuses_unknown_keys_and_feature_dict_keeps_its_shape():
    with pytest.raises(ValueError, match="unknown PipelineConfig fields"):
        PipelineConfig.from_dict({"trackers": None})
    assert "window_height" not in FeatureConfig().to_dict()  # as model files have always written it
    assert FeatureConfig(window_height=24).to_dict()["window_height"] == 24


@pytest.mark.parametrize("kw, err", [({"traffic": "middle"}, ValueError), ({"horizon": 1.5}, ValueError),
                                     ({"horizon": "middle"}, ValueError), ({"horizon": True}, ValueError),
                                     ({"tracker": HeatConfig()}, TypeError), ({"refine": "yes"}, TypeError),
                                     ({"heat": None}, TypeError), ({"oncoming": None}, TypeError),
                                     ({"model": 3}, TypeError)])
def test_pipeline_config_refuses(kw, err):
    with pytest.raises(err):
        PipelineConfig(**kw)


def test_guided_search_needs_the_tracker():
    assert PipelineConfig().planned == GuidedSearch()
    assert PipelineConfig(tracker=None).planned is None
    assert PipelineConfig(guided=GuidedSearch(every=1)).planned is None  # a full scan every frame
    assert PipelineConfig().without("tracker", "refine", "oncoming") == PipelineConfig(tracker=None, refine=None,
                                                                                      oncoming=False)


@pytest.mark.parametrize("cmd", [["video", "in.mp4", "--boxes", "b.txt"], ["eval", "--gt", "g.txt", "--video", "v.mp4"],
                                 ["bench"], ["batch", "in.mp4", "--out", "o"]])
def test_the_cli_builds_one_pipeline_config(cmd):
    from fastdet.cli._args import pipeline_config
    from fastdet.cli.main import build_parser

    parse = build_parser().parse_args
    assert pipeline_config(parse(cmd)) == PipelineConfig()
    flags = ["--no-oncoming", "--traffic", "left", "--no-refine", "--full-search"]
    want = PipelineConfig(oncoming=False, traffic="left", refine=None, guided=None)
    if cmd[0] != "bench":
        flags += ["--horizon", "off"]
        want = replace(want, horizon=None)
    if cmd[0] != "bench":
        flags += ["--no-track"]
        want = replace(want, tracker=None)
    assert pipeline_config(parse([*cmd, *flags])) == want


def test_a_deleted_stage_s_fields_load_when_off_and_keep_the_digest():
    # the side-view component was deleted (docs/accuracy.md, "Deleted stages"): a config written
    # with it off still loads, one with it on is refused in one line, and the digest of today's
    # default config is what it was while the stage existed (batch manifests resume)
    old = {**PipelineConfig().to_dict(), **PipelineConfig._RETIRED}
    assert PipelineConfig.from_dict(old) == PipelineConfig()
    assert "side" not in PipelineConfig().to_dict() and "side" in PipelineConfig().digest_dict()
    assert PipelineConfig().digest() == "73f1a5b6c40c08e5"
    # a nested config's deleted fields count too (the tracker's queue gate)
    assert PipelineConfig().digest_dict()["tracker"]["behind_speed"] == 0.1
    assert "behind_speed" not in PipelineConfig().to_dict()["tracker"]
    with pytest.raises(ValueError, match="PipelineConfig.side: this stage was deleted"):
        PipelineConfig.from_dict({**old, "side": True})
    with pytest.raises(ValueError, match="side_heat"):
        PipelineConfig.from_dict({"side_heat": HeatConfig(threshold=1).to_dict()})


def test_the_small_vehicle_component_s_fields_are_retired_too():
    old = {**PipelineConfig().to_dict(), "small": False, "small_check": -4.6}
    assert PipelineConfig.from_dict(old) == PipelineConfig()
    with pytest.raises(ValueError, match="PipelineConfig.small: this stage was deleted"):
        PipelineConfig.from_dict({"small": "small.npz"})


def test_self_calibration_is_retired_and_off_is_read():
    assert PipelineConfig.from_dict({"selfcal": None}) == PipelineConfig()
    assert "selfcal" not in PipelineConfig().digest_dict()  # it was left out of the dict while off
    with pytest.raises(ValueError, match="PipelineConfig.selfcal: this stage was deleted"):
        PipelineConfig.from_dict({"selfcal": {"scans": 5}})


def test_the_perspective_stage_is_retired_and_its_null_kept_in_the_digest():
    # written as null while off (not left out, as selfcal was): the digest still holds it
    assert PipelineConfig.from_dict({**PipelineConfig().to_dict(), "perspective": None}) == PipelineConfig()
    assert "perspective" not in PipelineConfig().to_dict()
    assert PipelineConfig().digest_dict()["perspective"] is None
    with pytest.raises(ValueError, match="PipelineConfig.perspective: this stage was deleted"):
        PipelineConfig.from_dict({"perspective": {"min_tracks": 2}})

"""NeighbourSplit: checks and JSON round trip."""
from __future__ import annotations

import pytest

from fastdet.config import NeighbourSplit, PipelineConfig


@pytest.mark.parametrize("bad", [dict(min_aspect=0), dict(bandwidth=-1), dict(scale_bandwidth=0),
                                 dict(min_weight=1.5), dict(inside=-0.1), dict(max_overlap=2),
                                 dict(max_frame_windows=1), dict(max_frame_windows=300.0),
                                 dict(max_frame_windows=True)])
def test_bad_values_are_refused(bad):
    with pytest.raises(ValueError):
        NeighbourSplit(**bad)


def test_round_trip_and_on_by_default():
    c = NeighbourSplit(min_aspect=2.0)
    assert NeighbourSplit.from_dict(c.to_dict()) == c
    on = PipelineConfig(split=c)
    assert PipelineConfig.from_dict(on.to_dict()) == on
    assert PipelineConfig().split == NeighbourSplit()
    # off is written as such (a dict without the key reads as the default, on)
    off = PipelineConfig(split=None)
    assert off.to_dict()["split"] is None and PipelineConfig.from_dict(off.to_dict()) == off
    assert PipelineConfig.from_dict({}).split == NeighbourSplit()
    with pytest.raises(TypeError):
        PipelineConfig(split=True)  # type: ignore[arg-type]


def test_the_frame_budget_at_its_default_leaves_the_dict_and_digest_as_before():
    c = NeighbourSplit()
    assert "max_frame_windows" not in c.to_dict() and NeighbourSplit.from_dict(c.to_dict()) == c
    # the digest of the fields it had before the budget existed
    before = {"min_aspect": 1.8, "min_weight": 0.5, "bandwidth": 0.25, "scale_bandwidth": 0.3, "inside": 0.5,
              "max_overlap": 0.3}
    assert c.to_dict() == before
    other = NeighbourSplit(max_frame_windows=300)
    assert other.to_dict() == {**before, "max_frame_windows": 300}
    assert NeighbourSplit.from_dict(other.to_dict()) == other and other.digest() != c.digest()
    assert PipelineConfig.from_dict(PipelineConfig(split=other).to_dict()).split == other

"""NeighbourSplit: checks and JSON round trip."""
from __future__ import annotations

import pytest

from fastdet.config import NeighbourSplit, PipelineConfig


@pytest.mark.parametrize("bad", [dict(min_aspect=0), dict(bandwidth=-1), dict(scale_bandwidth=0),
                                 dict(min_weight=1.5), dict(inside=-0.1), dict(max_overlap=2)])
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

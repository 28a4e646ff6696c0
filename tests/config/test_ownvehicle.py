"""OwnVehicleConfig: checks, frame counts at a frame rate, JSON round trip."""
from __future__ import annotations

import pytest

from fastdet.config import OwnVehicleConfig, PipelineConfig


@pytest.mark.parametrize("bad", [dict(min_still=1.5), dict(max_fraction=-0.1), dict(max_area=2.0), dict(gap_s=0),
                                 dict(frames_s=-1), dict(work_rows=8), dict(cells=2), dict(every=0),
                                 dict(min_pairs=0), dict(min_gradient=300), dict(bar_level=-1), dict(every=1.5)])
def test_bad_values_are_refused(bad):
    with pytest.raises(ValueError):
        OwnVehicleConfig(**bad)


def test_frames_at_a_frame_rate_and_round_trip():
    c = OwnVehicleConfig()
    assert c.gap(25) == 8 and c.gap(None) == 8 and c.gap(60) == 18 and OwnVehicleConfig(gap_s=0.01).gap(25) == 1
    assert c.n_frames(25) == 75 and c.n_frames(30) == 90
    assert OwnVehicleConfig.from_dict(c.to_dict()) == c
    on = PipelineConfig(own_vehicle=OwnVehicleConfig(min_still=0.7))
    assert PipelineConfig.from_dict(on.to_dict()) == on
    assert PipelineConfig().own_vehicle == OwnVehicleConfig()  # on by default
    off = PipelineConfig(own_vehicle=None)
    assert PipelineConfig.from_dict(off.to_dict()) == off  # off survives the round trip
    old = PipelineConfig().to_dict()
    del old["own_vehicle"]
    assert PipelineConfig.from_dict(old) == PipelineConfig()  # a dict from before the field: the default
    with pytest.raises(TypeError):
        PipelineConfig(own_vehicle=0.5)  # type: ignore[arg-type]

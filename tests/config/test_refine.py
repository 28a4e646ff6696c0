"""fastdet/config/refine.py: RefineConfig's checks, the options left out of its dict while off,
round trip (the refinement it configures: tests/video/test_refine.py)."""
from __future__ import annotations

import json
import math

import pytest

from fastdet.config import RefineConfig


@pytest.mark.parametrize("bad", [{"iterations": 0}, {"max_shift": -0.1}, {"max_log_scale": -1.0},
                                 {"min_step": -1.0}, {"max_total_log_scale": float("inf")},
                                 {"max_total_log_scale": float("nan")}, {"min_step": float("nan")}])
def test_refine_config_refuses(bad):
    with pytest.raises(ValueError):
        RefineConfig(**bad)


def test_off_options_left_out_of_the_dict_and_round_trip():
    # off by default, and left out of the config's dict (its digest as before they existed)
    assert "min_step" not in RefineConfig().to_dict() and "max_total_log_scale" not in RefineConfig().to_dict()
    assert RefineConfig.from_dict(RefineConfig(min_step=0.1).to_dict()).min_step == 0.1
    on = RefineConfig(iterations=1, parts=[0, 1.0], min_step=0.05, max_total_log_scale=math.log(2))
    assert on.parts == (0, 1) and all(type(p) is int for p in on.parts)
    back = RefineConfig.from_dict(json.loads(json.dumps(on.to_dict())))
    assert back == on and back.digest() == on.digest() != RefineConfig().digest()

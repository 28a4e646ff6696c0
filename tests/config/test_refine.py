"""fastdet/config/refine.py: RefineConfig's checks, the options left out of its dict while off,
round trip (the refinement it configures: tests/video/test_refine.py)."""
from __future__ import annotations

import json
import math

import pytest

from fastdet.config import RefineConfig


@pytest.mark.parametrize("bad", [{"iterations": 0}, {"max_shift": -0.1}, {"max_log_scale": -1.0}])
def test_refine_config_refuses(bad):
    with pytest.raises(ValueError):
        RefineConfig(**bad)


def test_round_trip():
    on = RefineConfig(iterations=1, parts=[0, 1.0], max_log_scale=math.log(2))
    assert on.parts == (0, 1) and all(type(p) is int for p in on.parts)
    back = RefineConfig.from_dict(json.loads(json.dumps(on.to_dict())))
    assert back == on and back.digest() == on.digest() != RefineConfig().digest()

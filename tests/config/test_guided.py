"""fastdet/config/guided.py: GuidedSearch's checks and round trip (the search it steers:
tests/video/test_guided.py)."""
from __future__ import annotations

import pytest

from fastdet.config import GuidedSearch


def test_config():
    g = GuidedSearch()
    assert GuidedSearch.from_dict(g.to_dict()) == g and not g.full and GuidedSearch(every=1).full
    for bad in ({"every": 0}, {"every": 2.5}, {"margin": -1}, {"memory": 0}, {"scales": (2.0, 1.0)}):
        with pytest.raises(ValueError):
            GuidedSearch(**bad)

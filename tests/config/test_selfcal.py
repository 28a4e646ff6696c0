"""fastdet/config/selfcal.py: SelfCalibration's checks (the offset it configures:
tests/video/test_selfcal.py)."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.config import SelfCalibration


@pytest.mark.parametrize("kw", [{"scans": 0}, {"scans": 1.5}, {"rate": 0.0}, {"rate": 1.0}, {"level": np.inf},
                                {"max_shift": -1.0}, {"max_shift": np.inf}])
def test_bad_settings_are_refused(kw):
    with pytest.raises(ValueError):
        SelfCalibration(**kw)

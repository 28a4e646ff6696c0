"""Where the shared data lives, and the sample clip that ships in the package.

``$FASTDET_DATA`` if set; otherwise ``../shared/data`` beside the source checkout, or
beside the current directory when fastdet is installed elsewhere.
"""
from __future__ import annotations

import os
from pathlib import Path

_CHECKOUT_DEFAULT = Path(__file__).resolve().parent.parent.parent / "shared" / "data"
_SAMPLE = Path(__file__).resolve().parent / "samples" / "test_video.mp4"


def data_dir() -> Path:
    """The data folder (it may not exist: callers check and say so)."""
    env = os.environ.get("FASTDET_DATA")
    if env:
        return Path(env)
    for cand in (_CHECKOUT_DEFAULT, Path.cwd().parent / "shared" / "data", Path.cwd() / "shared" / "data"):
        if cand.is_dir():
            return cand
    return _CHECKOUT_DEFAULT


def sample_video() -> Path:
    """The sample clip that ships with fastdet: 38 frames, 1280x720, 25 fps, two cars ahead
    on a highway (Udacity CarND-Vehicle-Detection, MIT). It needs no data folder."""
    return _SAMPLE

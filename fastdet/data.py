"""Where the shared data lives.

``$FASTDET_DATA`` if set; otherwise ``../shared/data`` beside the source checkout, or
beside the current directory when fastdet is installed elsewhere.
"""
from __future__ import annotations

import os
from pathlib import Path

_CHECKOUT_DEFAULT = Path(__file__).resolve().parent.parent.parent / "shared" / "data"


def data_dir() -> Path:
    """The data folder (it may not exist: callers check and say so)."""
    env = os.environ.get("FASTDET_DATA")
    if env:
        return Path(env)
    for cand in (_CHECKOUT_DEFAULT, Path.cwd().parent / "shared" / "data", Path.cwd() / "shared" / "data"):
        if cand.is_dir():
            return cand
    return _CHECKOUT_DEFAULT

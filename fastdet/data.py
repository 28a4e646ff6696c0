"""Where the shared data lives: ``$FASTDET_DATA``, default ``../shared/data`` beside the checkout."""
from __future__ import annotations

import os
from pathlib import Path

_DEFAULT = Path(__file__).resolve().parent.parent.parent / "shared" / "data"


def data_dir() -> Path:
    """The data folder: ``$FASTDET_DATA`` if set, else ``<checkout>/../shared/data``."""
    env = os.environ.get("FASTDET_DATA")
    return Path(env) if env else _DEFAULT

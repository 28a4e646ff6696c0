"""Small synthetic label sets for the reader tests: pictures (real JPEG/PNG files, tiny and
black), and the one-line-error check every malformed input must pass."""
from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet.errors import DataError


def picture(path: Path, width: int = 640, height: int = 360) -> Path:
    """A black ``width x height`` picture at ``path`` (format from the suffix)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.zeros((height, width, 3), np.uint8))
    return path


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def one_error(call, file: Path | str, *words: str, line: int | None = None) -> str:
    """``call()`` raises exactly one :class:`DataError` whose message is one line naming
    ``file`` (and ``line N`` when given) and holding every one of ``words``; the message."""
    with pytest.raises(DataError) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg, msg
    assert str(file) in msg, (str(file), msg)
    if line is not None:
        assert re.search(rf"\bline {line}\b", msg), (line, msg)
    for w in words:
        assert w in msg, (w, msg)
    return msg

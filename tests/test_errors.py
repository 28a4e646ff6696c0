"""fastdet/errors.py: which errors are the user's (caught as ValueError too), and one_line (what a
summary or a manifest records). What the CLI prints for them: tests/cli/test_main.py."""
from __future__ import annotations

import pytest

from fastdet.errors import DataError, FastdetError, ModelError, WriteError, one_line


def test_the_user_errors_are_fastdet_errors_and_value_errors():
    for cls in (ModelError, DataError, WriteError):
        assert issubclass(cls, FastdetError) and issubclass(cls, ValueError)
    assert issubclass(WriteError, DataError) and not issubclass(WriteError, ModelError)
    with pytest.raises(DataError):
        raise WriteError("o.txt: cannot write (No space left on device)")


@pytest.mark.parametrize("exc, line", [
    (DataError("x.mp4: not a video\nmore detail"), "x.mp4: not a video"),
    (FastdetError("  padded  "), "padded"),
    (KeyError("x"), "KeyError: 'x'"),
    (RuntimeError("first\nsecond"), "RuntimeError: first"),
    (RuntimeError(), "RuntimeError"),
    (WriteError(""), "WriteError"),
])
def test_one_line(exc, line):
    assert one_line(exc) == line

"""Exceptions that mean "the user gave us something wrong" (one-line message, no traceback)."""


class FastdetError(Exception):
    """A user-facing error: the CLI prints ``fastdet: <message>`` and exits non-zero."""


class ModelError(FastdetError, ValueError):
    """A model file is missing, malformed, of another format version or another feature config."""


class DataError(FastdetError, ValueError):
    """An input file (video, image, annotation, data folder) is missing or malformed."""


class WriteError(DataError):
    """Writing an output failed (a full disk, a temporary file that vanished, no
    permission): a fault of the place written to, not of the input; retrying may succeed."""


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message, for a summary or a manifest: a
    :class:`FastdetError`'s message as it is, any other exception prefixed with its type
    (``KeyError: 'x'``); the type alone when the message is empty."""
    text = str(exc).strip()
    if not text:
        return type(exc).__name__
    first = text.splitlines()[0]
    return first if isinstance(exc, FastdetError) else f"{type(exc).__name__}: {first}"

"""Exceptions that mean "the user gave us something wrong" (one-line message, no traceback)."""


class FastdetError(Exception):
    """A user-facing error: the CLI prints ``fastdet: <message>`` and exits non-zero."""


class ModelError(FastdetError, ValueError):
    """A model file is missing, malformed, of another format version or another feature config."""


class DataError(FastdetError, ValueError):
    """An input file (video, image, annotation, data folder) is missing or malformed."""

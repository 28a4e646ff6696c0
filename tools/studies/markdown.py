"""Markdown tables of the studies' printouts: the separator line made from the header, so it
always has the header's number of columns."""
from __future__ import annotations

import re
from collections.abc import Iterable

_BAR = re.compile(r"(?<!\\)\|")  # a column bar (an escaped ``\|`` is text)


def columns(header: str) -> int:
    """The number of columns of a markdown table line ``| a | b |`` (2 here)."""
    return max(len(_BAR.findall(header.strip())) - 1, 0)


def table(header: str, rows: Iterable[str]) -> str:
    """``header`` (``| a | b |``), its separator (``|---|---|``) and ``rows`` (table lines),
    one a line."""
    return "\n".join([header, "|" + "---|" * columns(header), *rows])

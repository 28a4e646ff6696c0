"""tools/studies/markdown.py: a table's separator has the header's number of columns."""
from __future__ import annotations

from tools.studies.markdown import columns, table


def test_the_separator_follows_the_header():
    assert columns("| a | b |") == 2 and columns("  | one |  ") == 1 and columns("") == 0
    assert columns(r"| x \| y | z |") == 2  # an escaped bar is text
    assert table("| a | b | c |", ["| 1 | 2 | 3 |", "| 4 | 5 | 6 |"]) == \
        "| a | b | c |\n|---|---|---|\n| 1 | 2 | 3 |\n| 4 | 5 | 6 |"
    assert table("| a |", iter([])) == "| a |\n|---|"

"""tools/studies/band_cost.py: the ``--bands`` spec the band studies share."""
from __future__ import annotations

from fastdet.config import SearchBand
from tools.studies.band_cost import parse_bands


def test_parse_bands_with_and_without_columns():
    assert parse_bands("1:400:496,2:400:592:100:900,0.75:380:440") == (
        SearchBand(1.0, 400, 496), SearchBand(2.0, 400, 592, 100, 900), SearchBand(0.75, 380, 440))

"""tools/studies/tolerance.py: the options to searches, the full-scan cost count, the command line."""
from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from fastdet.config import PipelineConfig, oncoming_search
from fastdet.video import make_detector
from tools.studies import tolerance as tol
from tools.studies.band_cost import scan_cost


def _args(**kw: object) -> argparse.Namespace:
    a = dict(band_slack=None, slack_threshold=None)
    a.update(kw)
    return argparse.Namespace(**a)


def test_options_to_searches() -> None:
    main, oncoming = tol.searches(_args())
    assert main == PipelineConfig().search and oncoming == oncoming_search(PipelineConfig().traffic)
    main, oncoming = tol.searches(_args(band_slack="0.05,0", slack_threshold=float("nan")))
    assert main.slack_threshold is None
    assert all(b.slack_above == 0.05 for b in main.bands if b.has_slack)
    assert sum(b.has_slack for b in main.bands) == sum(b.has_slack for b in PipelineConfig().search.bands)
    assert oncoming == oncoming_search(PipelineConfig().traffic)
    assert tol.parse_slack("0.03,0") == 0.03 == tol.parse_slack("0.03") and tol.parse_slack("0,0") is None
    with pytest.raises(SystemExit, match="ABOVE or ABOVE,0"):
        tol.parse_slack("0.03,0,1")
    with pytest.raises(SystemExit, match="slack below the bands was deleted"):  # one line, exit 2
        tol.parse_slack("0.03,0.03")
    # the detector of a run carries both searches
    det = tol.detector(_args(band_slack="0.05,0"), PipelineConfig())
    assert det.scorers[0].search.bands == main.bands and det.scorers[1].search.bands == oncoming.bands


def test_cost_counts_the_setting_against_today() -> None:
    today = scan_cost(make_detector())
    assert scan_cost(tol.detector(_args(), PipelineConfig())) == today
    more = scan_cost(tol.detector(_args(band_slack="0.05,0"), PipelineConfig()))
    for k in today:
        assert today[k] < more[k]  # more rows: more cells, windows and multiply-adds


def test_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], data: Path) -> None:
    assert tol.main(["--cost", "--band-slack", "0.05,0"]) == 0
    out = capsys.readouterr().out
    assert "hog_cells" in out and "x)" in out
    with pytest.raises(SystemExit):
        tol.main(["--out-dir", str(tmp_path)])  # no --loo: one line from argparse
    with pytest.raises(SystemExit):  # the deleted oncoming slack is no option
        tol.main(["--cost", "--oncoming-slack-below", "0.04"])
    assert (data / "annotations" / "test_small1.gt.txt").is_file()
    (tmp_path / "base").mkdir()
    (tmp_path / "base" / "results.json").write_text("{}")
    with pytest.raises(SystemExit, match="run .* first"):
        tol.main(["--loo", str(tmp_path), "--out-dir", str(tmp_path), "--why", "0.04", "--clips", "test_small1"])

"""tools/studies/options_table.py: settings to pipelines, the held-out models, the cost count,
the rule that says whether a setting holds, and the tables."""
from __future__ import annotations

from pathlib import Path

import pytest

from fastdet.config import NeighbourSplit, OwnVehicleConfig, PipelineConfig
from tools.studies import options_table as ot

CLIPS = ["boston_street", "test_small1", "test_video"]


def test_settings_to_pipelines() -> None:
    assert ot.parse_setting("base") == () and ot.config_for("base") == PipelineConfig()
    c = ot.config_for("split+own+both")
    assert c.split == NeighbourSplit()
    assert c.own_vehicle == OwnVehicleConfig()
    assert c.plausible == PipelineConfig().plausible
    assert c.traffic == "both"
    # every option but split and own (the defaults) changes the pipeline, and no two the same way
    assert ot.config_for("split") == PipelineConfig() and ot.config_for("nosplit").split is None
    assert ot.config_for("own") == PipelineConfig() and ot.config_for("noown").own_vehicle is None
    configs = [ot.config_for(o) for o in ot.OPTIONS if o not in ("split", "own")]
    assert all(c != PipelineConfig() for c in configs) and len(set(map(repr, configs))) == len(configs)
    for bad in ("both+nope", "small", "side", "persp", "pfilter", "both+both", "split+nosplit", "own+noown", ""):
        with pytest.raises(ValueError):
            ot.parse_setting(bad)
    for s in ot.DEFAULT_SETTINGS:
        ot.parse_setting(s)


def test_held_out_model(tmp_path: Path) -> None:
    assert ot.config_for("split", refine_model="/x/r.npz").refine_model == "/x/r.npz"
    (tmp_path / "refine_without_test_video.npz").write_bytes(b"")
    assert ot.held_out_model("test_video", tmp_path) == str(tmp_path / "refine_without_test_video.npz")
    with pytest.raises(SystemExit, match="refine_without_boston_street.npz missing"):
        ot.held_out_model("boston_street", tmp_path)


def test_cost_counts_what_each_option_adds() -> None:
    base = ot.search_cost(PipelineConfig())
    assert all(v > 0 for v in base.values())
    assert ot.search_cost(ot.config_for("nosplit+noown")) == base  # no band of their own
    both = ot.search_cost(ot.config_for("both"))
    assert all(both[k] > base[k] for k in base)  # the oncoming model searches both sides


def test_holds() -> None:
    base = {"boston_street": 0.30, "test_small1": 0.93, "test_video": 1.0}
    cheap = {"hog_cells": 1.2, "windows": 2.0, "score_macs": 1.1}
    assert ot.holds({"boston_street": 0.40, "test_small1": 0.93, "test_video": 0.996}, base, cheap) == (True, "holds")
    ok, why = ot.holds({"boston_street": 0.29, "test_small1": 0.95, "test_video": 1.0}, base, cheap)
    assert not ok and why.startswith("boston_street")
    ok, why = ot.holds({"boston_street": 0.5, "test_small1": 0.95, "test_video": 1.0}, base,
                       {**cheap, "hog_cells": 1.31})
    assert not ok and "hog_cells" in why
    ok, why = ot.holds({"boston_street": 0.5, "test_small1": 0.95}, base, cheap)
    assert not ok and "test_video" in why
    # a Udacity clip under 0.90 fails even where today is under it too
    ok, why = ot.holds({"boston_street": 0.5, "test_small1": 0.88, "test_video": 1.0},
                       {**base, "test_small1": 0.87}, cheap)
    assert not ok and "0.88 < 0.9" in why


def _score(f1: float) -> dict:
    return {"p": 0.5, "r": 0.5, "f1": f1, "fa": 0.25, "tp": 1, "fp": 1, "targets": 2,
            "widths": [[1, 2], [0, 0], [3, 4]]}


def test_tables_and_resume(tmp_path: Path) -> None:
    cost = {"hog_cells": 100.0, "windows": 10.0, "score_macs": 1000.0}
    dear = {"hog_cells": 140.0, "windows": 15.0, "score_macs": 1100.0}
    results = {"cost": {"base": cost, "split": cost, "noown": dear},
               "in": {"base": {c: _score(0.5) for c in CLIPS}},
               "loo": {"base": {c: _score(0.95) for c in CLIPS}, "split": {c: _score(0.96) for c in CLIPS},
                       "noown": {c: _score(0.99) for c in CLIPS}}}
    text = ot.tables(results, ["base", "split", "noown"], CLIPS)
    lines = text.splitlines()
    assert lines[2].startswith("| base | (today) | 1.00x | 1.00x | 1.00x | 0.95 | 0.95 | 0.95 | - |")
    assert lines[3] == "| split | --split-neighbours | 1.00x | 1.00x | 1.00x | 0.96 | 0.96 | 0.96 | holds |"
    assert lines[4] == "| noown | --no-own-vehicle | 1.40x | 1.50x | 1.10x | 0.99 | 0.99 | 0.99 | hog_cells 1.40x |"
    assert "| base | 0.50 (0.50/0.50, 0.25); 1/2, -, 3/4 |" in text
    results["loo"]["split"] = {c: _score(0.95) for c in CLIPS}
    assert ot.tables(results, ["split"], CLIPS).splitlines()[2].endswith("| holds (no change) |")
    # what an out-dir holds is read back; a rerun has nothing left to run
    for key in ot.KEYS:
        ot._save(results[key], tmp_path / f"{key}.json")
    assert ot.load(tmp_path) == results


def test_bad_setting_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert ot.main(["--out-dir", str(tmp_path), "--settings", "base,turbo"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown option 'turbo'" in err

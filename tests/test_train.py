"""End-to-end training on a small subset of the real crops, through the CLI."""
from __future__ import annotations

import numpy as np

from fastdet.cli import main
from fastdet.dataset import sequence_split
from fastdet.model import load_model


def test_train_cli_small_subset(data, tmp_path, capsys):
    out = tmp_path / "small.npz"
    args = ["train", "--data", str(data), "--out", str(out), "--max-per-folder", "60", "--seed", "3",
            "--no-progress", "--spatial-size", "16", "--hist-bins", "16"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "random split: accuracy" in text and "sequence split: accuracy" in text and "confusion" in text
    model = load_model(out)
    assert model.config.spatial_size == 16
    rep = model.metadata["training"]
    assert rep["data"]["vehicles"] == 5 * 60 and rep["data"]["non_vehicles"] == 2 * 60
    assert rep["sequence_split"]["accuracy"] > 0.85  # 420 crops still learn something real
    # deterministic for a seed
    out2 = tmp_path / "small2.npz"
    assert main([*args[:4], str(out2), *args[5:]]) == 0
    np.testing.assert_array_equal(load_model(out2).coef, model.coef)


def test_train_cli_bad_data_folder(tmp_path, capsys):
    assert main(["train", "--data", str(tmp_path), "--out", str(tmp_path / "m.npz"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "no 'vehicles' folder" in err and "Traceback" not in err


def test_sequence_split_is_contiguous_per_folder():
    groups = np.array(["a"] * 10 + ["b"] * 5)
    order = np.concatenate([np.arange(10)[::-1], np.arange(5)])
    tr, te = sequence_split(groups, order, seed=1)
    assert sorted(order[te[groups[te] == "a"]]) == [2, 3]
    assert len(set(tr) & set(te)) == 0 and len(tr) + len(te) == 15

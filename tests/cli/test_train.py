"""End-to-end training on a small subset of the real crops, through the CLI."""
from __future__ import annotations

import contextlib
import re

import numpy as np
import pytest

from fastdet.cli import main
from fastdet.model import load_model
from fastdet.train.dataset import sequence_split


@pytest.mark.slow
def test_train_cli_small_subset(data, tmp_path, capsys):
    out = tmp_path / "small.npz"
    # 30 crops a folder and 6 orientations: a third of the time of 60 and 9 (the fits), the same checks
    args = ["train", "--data", str(data), "--out", str(out), "--max-per-folder", "30", "--seed", "3",
            "--no-progress", "--spatial-size", "16", "--hist-bins", "16", "--orientations", "6"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "random split: accuracy" in text and "sequence split: accuracy" in text and "confusion" in text
    model = load_model(out)
    assert model.config.spatial_size == 16 and model.config.orientations == 6
    rep = model.metadata["training"]
    assert rep["data"]["vehicles"] == 5 * 30 and rep["data"]["non_vehicles"] == 2 * 30
    assert rep["sequence_split"]["accuracy"] > 0.85  # 210 crops still learn something real (0.95)
    # deterministic for a seed (the model is the final fit on every crop, whatever held-out
    # evaluations ran before it: the second run makes one of them, not both)
    out2 = tmp_path / "small2.npz"
    assert main([*args[:4], str(out2), *args[5:], "--split", "random"]) == 0
    np.testing.assert_array_equal(load_model(out2).coef, model.coef)
    np.testing.assert_array_equal(load_model(out2).intercept, model.intercept)


def test_train_cli_bad_data_folder(tmp_path, capsys):
    assert main(["train", "--data", str(tmp_path), "--out", str(tmp_path / "m.npz"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "no vehicles/ folder" in err and str(tmp_path) in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "m.npz").exists()


def test_sequence_split_is_contiguous_per_folder():
    groups = np.array(["a"] * 10 + ["b"] * 5)
    order = np.concatenate([np.arange(10)[::-1], np.arange(5)])
    tr, te = sequence_split(groups, order, seed=1)
    assert sorted(order[te[groups[te] == "a"]]) == [2, 3]
    assert len(set(tr) & set(te)) == 0 and len(tr) + len(te) == 15


@pytest.mark.slow
def test_train_wide_window_model(data, tmp_path, capsys):
    """--window-rows trains on the middle rows; hard negatives of any size are fitted to the window."""
    import cv2

    neg = tmp_path / "neg"
    neg.mkdir()
    rng = np.random.default_rng(0)
    for i in range(4):  # one of the window's own size, others 64x64 (rows are cut) and odd (resized)
        shape = [(24, 64, 3), (64, 64, 3), (30, 50, 3), (24, 64, 3)][i]
        cv2.imwrite(str(neg / f"n{i}.png"), rng.integers(0, 256, shape, dtype=np.uint8))
    out = tmp_path / "wide.npz"
    assert main(["train", "--data", str(data), "--out", str(out), "--window-rows", "20", "44",
                 "--max-per-folder", "30", "--split", "sequence", "--no-progress", "--orientations", "9",
                 "--negatives", str(neg)]) == 2  # mixed sizes: refused
    assert "different sizes" in capsys.readouterr().err
    for f in neg.glob("*.png"):
        if cv2.imread(str(f)).shape[:2] != (24, 64):
            f.unlink()
    assert main(["train", "--data", str(data), "--out", str(out), "--window-rows", "20", "44",
                 "--max-per-folder", "30", "--split", "sequence", "--no-progress", "--orientations", "9",
                 "--negatives", str(neg)]) == 0
    m = load_model(out)
    assert (m.config.win_h, m.config.win_w) == (24, 64)
    rep = m.metadata["training"]
    assert rep["window_top"] == 20 and rep["data"]["hard_negatives"] == 2
    assert main(["train", "--data", str(data), "--out", str(out), "--window-rows", "40", "30"]) == 2


@pytest.mark.parametrize("opts, msg", [
    (["--truncate", "1.5"], "fraction in [0, 1]"),
    (["--reencode", "-0.1"], "fraction in [0, 1]"),
    (["--jpeg-quality", "90", "30"], "--jpeg-quality must satisfy"),
    (["--truncate", "0.5", "--truncate-keep", "0.9", "0.6"], "--truncate-keep must satisfy"),
])
def test_train_cli_refuses_bad_augmentation_options(data, tmp_path, capsys, opts, msg):
    with pytest.raises(SystemExit) if "fraction" in msg else contextlib.nullcontext():
        rc = main(["train", "--data", str(data), "--out", str(tmp_path / "m.npz"), "--no-progress", *opts])
        assert rc == 2
    assert msg in capsys.readouterr().err and not (tmp_path / "m.npz").exists()


def _yolo_set(root, data):
    """A YOLO set of two Udacity test pictures, the black car of test1 boxed (class 0 car)."""
    import shutil

    (root / "images").mkdir(parents=True)
    (root / "labels").mkdir()
    (root / "classes.txt").write_text("car\n")
    for name in ("test1", "test4"):
        shutil.copy(data / "test_images" / f"{name}.jpg", root / "images" / f"{name}.jpg")
        # the black car at x 815-945, y 395-505 of 1280x720 (README's crop), normalised
        (root / "labels" / f"{name}.txt").write_text(
            f"0 {880 / 1280:.6f} {450 / 720:.6f} {130 / 1280:.6f} {110 / 720:.6f}\n")
    return root


def test_train_learns_from_labelled_pictures_too(data, tmp_path, capsys):
    spec = f"yolo:{_yolo_set(tmp_path / 'set', data)}"
    out = tmp_path / "m.npz"
    args = ["train", "--data", str(data), "--out", str(out), "--max-per-folder", "8", "--split", "random",
            "--no-progress", "--frames", spec]
    assert main(args) == 0
    text = capsys.readouterr().out
    # 2 pictures: 2 boxes + 2 jittered copies each, mirrored; 8 background windows each + hard negatives
    m = re.search(r"(\d+) vehicle crops, (\d+) background, (\d+) hard negatives", text)
    assert m and int(m.group(1)) == 4 and int(m.group(2)) == 16, text
    from fastdet.model import load_model

    model = load_model(out)
    assert model.metadata["training"]["data"]["extra_positives"] == 4


def test_train_frames_spec_errors_are_one_line_before_work(data, tmp_path, capsys):
    rc = main(["train", "--data", str(data), "--out", str(tmp_path / "m.npz"), "--frames", f"voc:{tmp_path}/nope"])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nope" in err
    assert not (tmp_path / "m.npz").exists()

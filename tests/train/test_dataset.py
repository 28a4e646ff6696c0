"""fastdet/train/dataset.py: a data set thinned to a few crops a folder while it is read equals
the whole data set read and then thinned (each folder's crops in time order, evenly spread);
the crops left out are not read."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet.errors import DataError
from fastdet.train.dataset import CropSet, load_crops, thinned


def _tree(root: Path) -> None:
    """vehicles/a (7 crops, numbered out of name order), vehicles/b/deep (3), non-vehicles/c (12);
    each crop's pixels tell which file it is."""
    k = 0
    for folder, n in (("vehicles/a", 7), ("vehicles/b/deep", 3), ("non-vehicles/c", 12)):
        d = root / folder
        d.mkdir(parents=True)
        for i in range(n):
            k += 1
            cv2.imwrite(str(d / f"img{(i * 5) % n}_{i}.png"), np.full((64, 64, 3), k, np.uint8))


def _thin_after(crops: CropSet, n: int) -> CropSet:
    """The obvious rule on a set read whole: per folder, the crops in time order, ``n`` of them
    at evenly spread positions (first and last included)."""
    keep = []
    for g in np.unique(crops.groups):
        m = np.flatnonzero(crops.groups == g)
        m = m[np.argsort(crops.order[m], kind="stable")]
        keep.append(m[np.linspace(0, len(m) - 1, min(n, len(m))).astype(int)])
    return crops.subset(np.sort(np.concatenate(keep)))


@pytest.mark.parametrize("n", [1, 2, 3, 5, 7, 12, 40])
def test_thinned_while_reading_equals_thinned_after(tmp_path: Path, n: int) -> None:
    _tree(tmp_path)
    whole = load_crops(tmp_path)
    assert len(whole) == 22
    got, want = load_crops(tmp_path, max_per_folder=n), _thin_after(whole, n)
    for field in ("images", "labels", "groups", "order"):
        np.testing.assert_array_equal(getattr(got, field), getattr(want, field), err_msg=field)
    assert len(got) == min(n, 7) + min(n, 3) + min(n, 12)


def test_the_crops_left_out_are_not_read(tmp_path: Path) -> None:
    _tree(tmp_path)
    files = sorted((tmp_path / "non-vehicles" / "c").iterdir(), key=lambda p: int(p.stem.split("_")[1]))
    files[5].write_bytes(b"not a png")  # the 6th of 12 in time order: thinning to 2 keeps the 1st and the 12th
    with pytest.raises(DataError, match="not a readable image"):
        load_crops(tmp_path)
    assert len(load_crops(tmp_path, max_per_folder=2)) == 6
    np.testing.assert_array_equal(thinned(12, 2), [0, 11])
    np.testing.assert_array_equal(thinned(5, None), np.arange(5))
    np.testing.assert_array_equal(thinned(5, 0), np.arange(5))


def _tiny(root: Path, n_pos: int, n_neg: int) -> Path:
    rng = np.random.default_rng(0)
    for folder, n in (("vehicles/a", n_pos), ("non-vehicles/b", n_neg)):
        (root / folder).mkdir(parents=True)
        for i in range(n):
            cv2.imwrite(str(root / folder / f"{i}.png"), rng.integers(0, 256, (64, 64, 3), np.uint8))
    return root


@pytest.mark.parametrize("n, split, msg", [
    (1, "both", "the random split holds out a fifth of each class: it needs at least 5 crops of each, got 1 vehicle"),
    (2, "random", "at least 5 crops of each, got 2 vehicle and 2 non-vehicle crops"),
    (1, "sequence", "the sequence split .* its training part has no vehicle crop .* a folder of at least 5 crops"),
])
def test_train_on_too_few_crops_for_its_split_is_one_line(tmp_path: Path, n: int, split: str, msg: str) -> None:
    """issue 34, item 14: ``train`` on 1 + 1, 2 + 2 crops, or 1 + 1 with ``--split sequence``
    ended in a scikit-learn traceback; now one line saying what the split needs, before any
    feature is computed."""
    from fastdet.config import FeatureConfig
    from fastdet.train.fit import train
    with pytest.raises(DataError, match=msg):
        train(_tiny(tmp_path, n, n), FeatureConfig(), split=split, flip=False, refit=False)


def test_train_on_one_crop_each_without_a_split_fits() -> None:
    from fastdet.train.dataset import check_splits
    check_splits(np.array([1, 0]), np.array(["a", "b"]), np.array([0, 0]), "none", 0)
    check_splits(np.array([1] * 5 + [0] * 5), np.array(["a"] * 5 + ["b"] * 5), np.tile(np.arange(5), 2), "both", 0)

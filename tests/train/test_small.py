"""Training the small-vehicle component: the data set's crops shrunk to 32x32, native-resolution
tiles as negatives, optional hard negatives of annotated frames (a tiny copy of the data set)."""
from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from fastdet.boxes import intersection
from fastdet.config import SMALL_FEATURES
from fastdet.train.dataset import find_pngs
from fastdet.train.fit import train
from fastdet.train.keyframes import read_annotated_frames
from fastdet.train.small import SmallRecipe, hard_negatives, mining_search, random_tiles, tile_negatives, train_small


@pytest.fixture(scope="module")
def tiny_data(data, tmp_path_factory) -> Path:
    """40 crops of each of two vehicle folders and two non-vehicle folders of the data set."""
    root = tmp_path_factory.mktemp("tiny")
    for sub in ("vehicles", "non-vehicles"):
        for folder, paths in list(find_pngs(data / sub).items())[:2]:
            dst = root / sub / folder.name
            dst.mkdir(parents=True)
            for p in paths[:40]:
                shutil.copy(p, dst / p.name)
    return root


def test_random_tiles_are_slices_of_their_image():
    rng = np.random.default_rng(1)
    imgs = rng.integers(0, 256, (5, 64, 64, 3), dtype=np.uint8)
    t = random_tiles(imgs, 32, 3, seed=7)
    assert t.shape == (15, 32, 32, 3)
    for k, tile in enumerate(t):
        im = imgs[k // 3]
        hits = [(y, x) for y in range(33) for x in range(33) if np.array_equal(im[y: y + 32, x: x + 32], tile)]
        assert hits
    np.testing.assert_array_equal(t, random_tiles(imgs, 32, 3, seed=7))
    assert random_tiles(imgs, 32, 0, seed=0).shape == (0, 32, 32, 3)
    with pytest.raises(ValueError, match="fit"):
        random_tiles(imgs, 80, 1, seed=0)


def test_recipe_checks():
    with pytest.raises(ValueError, match="square"):
        SmallRecipe(features=replace(SMALL_FEATURES, window_height=16))
    with pytest.raises(ValueError, match="64"):
        SmallRecipe(features=replace(SMALL_FEATURES, window=72, spatial_size=36))
    with pytest.raises(ValueError, match=">= 0"):
        SmallRecipe(tiles=-1)
    with pytest.raises(ValueError, match="C"):
        SmallRecipe(C=0)


def test_crop_size_shrinks_the_crops_with_inter_area(tiny_data):
    logs: list[str] = []
    model, report = train(tiny_data, SMALL_FEATURES, split="none", crop_size=32, progress=False, log=logs.append)
    assert report["crop_size"] == 32 and model is not None and model.config == SMALL_FEATURES
    # the model's own positives are the crops shrunk with INTER_AREA: they score as vehicles
    veh = [p for ps in find_pngs(tiny_data / "vehicles").values() for p in ps]
    crops = np.stack([cv2.resize(cv2.imread(str(p)), (32, 32), interpolation=cv2.INTER_AREA) for p in veh])
    assert (model.decision_function(crops) > 0).mean() > 0.9


def test_train_small_learns_vehicles_from_tiles_and_records_how(tiny_data, data):
    recipe = SmallRecipe(split="none")
    tiles = tile_negatives(tiny_data, recipe)
    assert tiles is not None and len(tiles) == 80 * recipe.tiles + 80 * recipe.part_tiles
    assert tiles.images.shape[1:] == (32, 32, 3) and not tiles.labels.any()
    m = train_small(tiny_data, recipe, command="python -m tools.scripts.small_model --out x.npz", log=lambda _: None)
    assert m.config == SMALL_FEATURES and m.classifier == "logreg"
    meta = m.metadata["small"]
    assert meta["command"].startswith("python -m tools.scripts.small_model")
    assert meta["recipe"]["tiles"] == 2 and meta["hard_negatives"] == 0 and meta["hard_negative_clips"] == []
    assert m.metadata["training"]["data"]["hard_negatives"] == len(tiles)
    # shrunk non-vehicle crops of the data set score below shrunk vehicle crops
    def shrunk(sub):
        ps = [p for v in find_pngs(data / sub).values() for p in v[200:230]]
        return np.stack([cv2.resize(cv2.imread(str(p)), (32, 32), interpolation=cv2.INTER_AREA) for p in ps])
    assert np.median(m.decision_function(shrunk("vehicles"))) > np.median(m.decision_function(shrunk("non-vehicles")))
    assert tile_negatives(tiny_data, replace(recipe, tiles=0, part_tiles=0)) is None

    # hard negatives of annotated frames: windows touching no annotated box, at most per_frame a frame
    frames = read_annotated_frames(data, "boston_street")[:3]
    hard = hard_negatives(m, frames, per_frame=5, seed=0)
    assert 0 < len(hard) <= 15 and hard.images.shape[1:] == (32, 32, 3)
    assert mining_search().shrink == "area"
    logs: list[str] = []
    m2 = train_small(tiny_data, recipe, frames=frames, base=m, log=logs.append)
    assert m2.metadata["small"]["hard_negative_clips"] == ["boston_street"]
    assert m2.metadata["small"]["hard_negatives"] == len(hard_negatives(m, frames, recipe.hard_per_frame, recipe.seed))
    assert any("hard negatives" in s for s in logs)


def test_mined_windows_touch_no_annotated_box(data):
    from fastdet.detect import Detector
    from fastdet.model import Model

    frames = read_annotated_frames(data, "boston_street")[:2]
    n = SMALL_FEATURES.n_features
    rng = np.random.default_rng(0)
    eager = Model(SMALL_FEATURES, rng.normal(size=n) * 0.01, 5.0, rng.normal(size=n), np.ones(n), "logreg")
    wins = Detector(eager, search=mining_search()).detect(frames[0].image).boxes
    assert len(wins) and (intersection(wins.astype(float), frames[0].boxes) > 0).any()  # some windows touch one
    hard = hard_negatives(eager, frames, per_frame=10**7, seed=0)
    # every window fires: what is kept is exactly those touching no annotated box
    want = sum(int((~(intersection(Detector(eager, search=mining_search()).detect(f.image).boxes.astype(float),
                                      f.boxes) > 0).any(1)).sum()) for f in frames)
    assert len(hard) == want > 0

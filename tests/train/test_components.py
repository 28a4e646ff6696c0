"""Training a detector component on crops of annotated frames (small recipe, one clip)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from fastdet.config import side_search
from fastdet.train.components import SIDE_RECIPE, ComponentRecipe, train_component
from fastdet.train.keyframes import background_crops, positive_crops, read_annotated_frames


@pytest.fixture(scope="module")
def frames(data):
    return read_annotated_frames(data, "boston_street")


def test_small_side_component_learns_its_positives(frames, data):
    recipe = replace(SIDE_RECIPE, jitter=1, background=10, data_negatives=300, hard_rounds=1)
    logs: list[str] = []
    m = train_component(recipe, frames, data, side_search(), log=logs.append)
    assert (m.config.win_w, m.config.win_h) == (64, 32) and m.classifier == "logreg"
    meta = m.metadata["component"]
    assert meta["clips"] == ["boston_street"] and meta["frames"] == len(frames)
    assert meta["recipe"]["aspect"] == [1.6, None] and meta["recipe"]["name"] == "side"
    n_pos = len(positive_crops(frames, 64, 32, recipe.aspect, recipe.min_width, recipe.margin, recipe.jitter))
    assert meta["data"]["positives"] == 2 * n_pos > 0
    assert meta["data"]["data_negatives"] == 300 and len(meta["data"]["hard_negatives"]) == 1
    assert any("round 1" in s for s in logs)
    # its own training positives score above the background of the same frames
    pos = positive_crops(frames, 64, 32, recipe.aspect, recipe.min_width, recipe.margin)
    bg = background_crops(frames, 64, 32, 10, seed=99)
    sp, sb = m.decision_function(pos), m.decision_function(bg)
    assert np.median(sp) > 0 > np.median(sb)


def test_recipe_checks_and_no_positive(frames, data):
    with pytest.raises(ValueError, match="aspect"):
        ComponentRecipe("x", SIDE_RECIPE.features, (2.0, 1.0))
    with pytest.raises(ValueError, match="C"):
        replace(SIDE_RECIPE, C=0)
    with pytest.raises(ValueError, match="no annotated box"):
        train_component(replace(SIDE_RECIPE, aspect=(50.0, 60.0), data_negatives=10), frames, data, side_search())

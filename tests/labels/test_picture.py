"""fastdet.labels.picture: the AnnotatedPicture type, the size rule, pixels of a still."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fastdet.errors import DataError
from fastdet.labels.picture import AnnotatedPicture, split_small

from .synth import one_error, picture


def test_fields_and_boxes(tmp_path):
    pic = AnnotatedPicture("s", "cam", "a.jpg", str(tmp_path / "a.jpg"), 640, 360,
                           targets=[[1, 2, 100, 80]], ignores=[])
    assert pic.path == tmp_path / "a.jpg"
    assert pic.targets.shape == (1, 4) and pic.ignores.shape == (0, 4) and pic.targets.dtype == np.float64
    assert pic.boxes.shape == (1, 4) and pic.complete and pic.frame is None
    assert pic.labelled_by == "human" and pic.human
    with pytest.raises(dataclasses.FrozenInstanceError):
        pic.camera = "other"  # type: ignore[misc]
    assert not dataclasses.replace(pic, labelled_by="teacher").human
    with pytest.raises(ValueError, match="labelled_by"):
        dataclasses.replace(pic, labelled_by="robot")


def test_split_small():
    t, s = split_small(np.array([[0, 0, 39.9, 10], [0, 0, 40, 10]]), 1280)
    np.testing.assert_array_equal(t, [[0, 0, 40, 10]])
    np.testing.assert_array_equal(s, [[0, 0, 39.9, 10]])
    t, s = split_small(np.zeros((0, 4)), 640)
    assert t.shape == s.shape == (0, 4)


def test_load_a_still_and_refuse_another_size(tmp_path):
    p = picture(tmp_path / "a.png", 64, 48)
    pic = AnnotatedPicture("s", "c", "a.png", p, 64, 48)
    assert pic.load().shape == (48, 64, 3)
    wrong = dataclasses.replace(pic, width=65)
    one_error(wrong.load, p, "the picture is 64x48, its labels are for 65x48")
    one_error(dataclasses.replace(pic, path=tmp_path / "gone.png").load, tmp_path / "gone.png", "not found")
    with pytest.raises(DataError):
        AnnotatedPicture("s", "c", "v", tmp_path / "gone.mp4", 64, 48, frame=3).load()

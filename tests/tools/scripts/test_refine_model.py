"""tools/scripts/refine_model.py (the bundled box regressor), on the test images alone: it
writes a regressor fastdet loads, that records what it was fitted on and moves boxes."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.video.refine import load_regressor, refine_boxes
from tools.scripts import refine_model


def test_fits_on_the_test_images_and_writes_a_loadable_regressor(data, tmp_path, capsys):
    out = tmp_path / "refine.npz"
    assert refine_model.main([str(out), "--clips", "", "--per-box", "2"]) == 0
    reg = load_regressor(out)
    assert reg.metadata["trained_on"] == ["test_images"]
    assert reg.metadata["fit"]["samples"] > 0 and "wrote" in capsys.readouterr().out
    frame, boxes, _ = refine_model.test_images()[0]
    moved = refine_boxes(frame, boxes.astype(np.float64), reg)
    assert moved.shape == boxes.shape and not np.array_equal(moved, boxes)


def test_unknown_clip_is_refused(data, tmp_path):
    with pytest.raises(SystemExit, match="unknown clip"):
        refine_model.main([str(tmp_path / "r.npz"), "--clips", "nope"])
    assert not (tmp_path / "r.npz").exists()



def test_size_inputs_are_no_option(data, tmp_path, capsys):
    """--size-inputs (the box's size among the inputs) was deleted: argparse refuses it."""
    with pytest.raises(SystemExit):
        refine_model.main([str(tmp_path / "r.npz"), "--clips", "", "--size-inputs", "log_width"])
    assert "unrecognized arguments: --size-inputs" in capsys.readouterr().err
    assert not (tmp_path / "r.npz").exists()

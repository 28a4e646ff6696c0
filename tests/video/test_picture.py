"""The single-picture search: PictureSearch's bands cover the whole picture at every scale,
and fastdet.detect_picture gives the boxes `fastdet image` writes."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from fastdet.config import PictureSearch
from fastdet.train.windows import dense_search


def test_bands_cover_every_row_at_every_scale():
    ps = PictureSearch()
    s = ps.search((720, 1280))
    scales = [b.scale for b in s.bands]
    assert scales[0] == pytest.approx(40 / 64) and 64 * scales[-1] <= 720
    assert all(b2 / b1 == pytest.approx(math.sqrt(2)) for b1, b2 in zip(scales, scales[1:]))
    assert all(b.y_start == 0 and b.y_stop == 720 and b.x_start == 0 for b in s.bands)
    assert s.reference_shape is None and s.border == 0 and s.cells_per_step == 2
    # the same bands as the placement-free search of fastdet.train.windows
    d = dense_search((720, 1280), steps=2, cells_per_step=2)
    assert [(b.scale, b.y_start, b.y_stop, b.x_stop) for b in d.bands] == \
        [(pytest.approx(b.scale), b.y_start, b.y_stop, b.x_stop) for b in s.bands]
    assert PictureSearch.from_dict(ps.to_dict()) == ps


@pytest.mark.parametrize("bad", [{"min_width": 0}, {"steps": 0}, {"boxes": "mean"}, {"nms_iou": 1.0},
                                 {"heat_threshold": 0}, {"max_height": 1.5}])
def test_bad_settings(bad):
    with pytest.raises(ValueError):
        PictureSearch(**bad)


def test_too_small_picture():
    with pytest.raises(ValueError, match="too small for the picture search"):
        PictureSearch().search((12, 12))


def test_detect_picture_is_what_image_writes(test_images, tmp_path):
    import fastdet
    from fastdet import cli

    img = cv2.imread(str(test_images[0]))
    d = fastdet.detect_picture(img)
    assert d.boxes.dtype == np.int32 and d.boxes.shape[1] == 4
    csv = tmp_path / "b.csv"
    assert cli.main(["image", str(test_images[0]), "--boxes", str(csv), "--no-progress"]) == 0
    rows = [ln.split(",") for ln in csv.read_text().splitlines()[1:]]
    assert [[int(v) for v in r[1:5]] for r in rows] == d.boxes.tolist()
    assert [float(r[5]) for r in rows] == pytest.approx(d.scores.tolist(), abs=1e-4)

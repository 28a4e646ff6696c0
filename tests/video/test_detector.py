"""fastdet/video/detector.py: make_detector builds the detector a PipelineConfig asks for (which
abilities pick which stages: tests/video/test_stages.py)."""
from __future__ import annotations

import pytest

from fastdet.config import PipelineConfig, oncoming_search
from fastdet.video import make_detector


def test_make_detector_puts_the_oncoming_search_on_the_side_traffic_comes_from():
    for side in ("right", "left", "both"):
        det = make_detector(PipelineConfig(traffic=side))
        assert det.scorers[1].search == oncoming_search(side)
    assert make_detector().scorers[1].search == oncoming_search("right")
    left = make_detector(PipelineConfig(traffic="left")).scorers[1].search.bands
    right = make_detector(PipelineConfig(traffic="right")).scorers[1].search.bands
    assert left != right
    with pytest.raises(ValueError, match="traffic"):
        make_detector(PipelineConfig(traffic="middle"))  # type: ignore[arg-type]


def test_a_side_view_component_is_searched_for_the_window_boxes_only(tmp_path, test_images):
    """make_detector searches a carried side-view component when the boxes are the window boxes
    (the model's record or the config's), not for the heat map, which takes the main model's
    windows only; the picture search leaves it out (it was chosen for a video's window boxes)."""
    import cv2

    from fastdet.train.blend import offset
    from fastdet.video.detector import BOXES_KEY
    from fastdet.video.picture import PictureDetector
    from tests.fakes import model_carrying_side

    model = model_carrying_side(cv2.imread(str(test_images[0])))
    nms = offset(model, 0.0, metadata={BOXES_KEY: "nms"}).save(tmp_path / "nms.npz")
    heat = offset(model, 0.0, metadata={BOXES_KEY: "heat"}).save(tmp_path / "heat.npz")
    assert len(make_detector(PipelineConfig(model=str(nms))).components) == 1
    assert make_detector(PipelineConfig(model=str(heat))).components == []
    assert len(make_detector(PipelineConfig(model=str(heat), boxes="nms")).components) == 1
    assert make_detector(PipelineConfig(model=str(nms), boxes="heat")).components == []
    pictures = PictureDetector(str(nms))
    assert pictures.model.side is None and pictures.detector((720, 1280)).components == []


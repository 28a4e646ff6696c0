"""fastdet.labels.rules: the box rules every reader applies (data README's target / ignore rule)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.errors import DataError
from fastdet.labels.rules import Box, apply_rules, check_box, class_kind, make_picture, normal_name


def box(x1, y1, x2, y2, vehicle=True, where="f.txt: line 3"):
    return Box(x1, y1, x2, y2, vehicle, where)


@pytest.mark.parametrize("width, narrowest", [(640, 24.0), (800, 25.0), (960, 30.0), (1280, 40.0), (320, 24.0)])
def test_size_rule_at_its_edge(width, narrowest):
    """The README's table: 40 px at 1280, 30 at 960, 25 at 800, 24 at 640 (and below)."""
    t, ig = apply_rules([box(10, 10, 10 + narrowest, 50), box(10, 10, 10 + narrowest - 0.01, 50)], width, 360)
    np.testing.assert_allclose(t, [[10, 10, 10 + narrowest, 50]])
    np.testing.assert_allclose(ig, [[10, 10, 10 + narrowest - 0.01, 50]])


def test_clipped_width_decides():
    """A car half out of the picture is judged by what is in view."""
    t, ig = apply_rules([box(-30, 0, 20, 40), box(-30, 0, 60, 40)], 640, 360)
    np.testing.assert_allclose(ig, [[0, 0, 20, 40]])
    np.testing.assert_allclose(t, [[0, 0, 60, 40]])


def test_ignore_regions_stay_ignores_and_are_clipped():
    t, ig = apply_rules([box(600, 300, 700, 400, vehicle=False)], 640, 360)
    assert t.shape == (0, 4)
    np.testing.assert_allclose(ig, [[600, 300, 640, 360]])


def test_zero_size_boxes_are_dropped():
    assert not check_box(box(5, 5, 5, 50), 640, 360)
    assert not check_box(box(5, 5, 50, 5), 640, 360)
    t, ig = apply_rules([box(5, 5, 5, 50), box(5, 5, 50, 5, vehicle=False)], 640, 360)
    assert t.shape == ig.shape == (0, 4)


@pytest.mark.parametrize("b, words", [
    (box(700, 10, 800, 50), "entirely outside the 640x360 picture"),
    (box(-100, 10, 0, 50), "entirely outside"),        # touching the left edge: no area inside
    (box(10, 360, 50, 400), "entirely outside"),
    (box(50, 10, 40, 50), "negative box size"),
    (box(float("nan"), 10, 40, 50), "not four finite numbers"),
])
def test_bad_boxes_name_where_they_were_read(b, words):
    with pytest.raises(DataError, match="^f.txt: line 3: .*" + words):
        apply_rules([box(0, 0, 100, 100), b], 640, 360)


@settings(max_examples=200, deadline=None)
@given(x1=st.floats(-500, 1000), y1=st.floats(-500, 1000), w=st.floats(0.01, 800), h=st.floats(0.01, 800),
       vehicle=st.booleans())
def test_every_kept_box_is_inside_and_not_empty(x1, y1, w, h, vehicle):
    b = box(x1, y1, x1 + w, y1 + h, vehicle)
    try:
        t, ig = apply_rules([b], 640, 360)
    except DataError as exc:
        assert "entirely outside" in str(exc)
        assert x1 + w <= 0 or y1 + h <= 0 or x1 >= 640 or y1 >= 360
        return
    both = np.concatenate([t, ig])
    assert both.shape == (1, 4)
    assert (both[:, :2] >= 0).all() and (both[:, 2] <= 640).all() and (both[:, 3] <= 360).all()
    assert (both[:, 2] > both[:, 0]).all() and (both[:, 3] > both[:, 1]).all()
    if not vehicle:
        assert len(t) == 0


def test_class_names():
    assert normal_name(" Person_sitting ") == "person sitting" and normal_name("DontCare") == "dontcare"
    assert class_kind("Car", "x") is True and class_kind("TRUCK", "x") is True
    assert class_kind("motorbike", "x") is False and class_kind("DontCare", "x") is False
    assert class_kind("person", "x") is None and class_kind("traffic light", "x") is None
    with pytest.raises(DataError, match="^a.xml: line 7: unknown class 'cra'"):
        class_kind("cra", "a.xml: line 7")


def test_make_picture(tmp_path):
    pic = make_picture(source="s", camera="c", name="n.jpg", path=tmp_path / "n.jpg", width=640, height=360,
                       boxes=[box(0, 0, 100, 100), box(0, 0, 10, 10)], complete=False)
    assert pic.targets.shape == (1, 4) and pic.ignores.shape == (1, 4)
    assert not pic.complete and pic.human and pic.frame is None

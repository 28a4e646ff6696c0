"""fastdet.video.nmsboxes: one box per vehicle from a frame's windows by non-maximum suppression
(``PipelineConfig(boxes='nms')``), checked against a plain greedy loop; the pipeline's box
formation (config, the model's record, the heat map by default)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.config import ONCOMING_MODEL_PATH, PipelineConfig
from fastdet.detections import FIRST_COMPONENT_PART, MAIN_PART, ONCOMING_PART, Detections
from fastdet.errors import ModelError
from fastdet.io.reader import FrameReader
from fastdet.model import load_model
from fastdet.train.blend import offset
from fastdet.video import VideoDetector
from fastdet.video.box_stages import HeatStage, TrackStage
from fastdet.video.detector import BOXES_KEY, box_formation
from fastdet.video.nmsboxes import NMS_INSIDE, NMS_IOU, NmsStage, nms_boxes
from fastdet.video.plausible import DENSE_DUPLICATES, duplicates
from tests.fakes import model_carrying_side
from tests.reference import box_iou, box_overlap_fraction


def greedy(boxes: np.ndarray, scores: np.ndarray, max_iou: float, max_inside: float = NMS_INSIDE) -> list[int]:
    """The rows kept by the textbook greedy suppression: best score first (ties: the earlier
    row), a box kept when it overlaps no kept box by IoU above ``max_iou`` and has no more than
    ``max_inside`` of its area inside one."""
    kept: list[int] = []
    for i in sorted(range(len(boxes)), key=lambda k: (-float(scores[k]), k)):
        if all(box_iou(boxes[i], boxes[j]) <= max_iou and box_overlap_fraction(boxes[i], boxes[j]) <= max_inside
               for j in kept):
            kept.append(i)
    return sorted(kept)


@st.composite
def windows(draw: st.DrawFn) -> Detections:
    n = draw(st.integers(0, 40))
    xy = draw(st.lists(st.tuples(st.integers(0, 200), st.integers(0, 120)), min_size=n, max_size=n))
    size = draw(st.lists(st.sampled_from([48, 64, 96, 128]), min_size=n, max_size=n))
    scores = draw(st.lists(st.sampled_from([0.55, 0.6, 0.7, 0.8, 0.9, 0.99]), min_size=n, max_size=n))
    part = draw(st.lists(st.sampled_from([MAIN_PART, MAIN_PART, ONCOMING_PART]), min_size=n, max_size=n))
    b = np.array([[x, y, x + s, y + s] for (x, y), s in zip(xy, size)], np.int32).reshape(-1, 4)
    return Detections(b, np.array(scores, np.float32), part=np.array(part, np.int8))


@settings(max_examples=200, deadline=None)
@given(windows())
def test_nms_boxes_are_the_greedy_loops_of_the_main_windows(w: Detections) -> None:
    got = nms_boxes(w)
    main = np.flatnonzero(w.part == MAIN_PART)
    want = main[greedy(w.boxes[main], w.scores[main], NMS_IOU)]
    np.testing.assert_array_equal(got.boxes, w.boxes[want])
    np.testing.assert_array_equal(got.scores, w.scores[want])
    assert got.boxes.dtype == np.int32 and got.scores.dtype == np.float32
    # no part column: every window is the main model's
    plain = nms_boxes(Detections(w.boxes, w.scores))
    np.testing.assert_array_equal(plain.boxes, w.boxes[greedy(w.boxes, w.scores, NMS_IOU)])
    # each rule alone: IoU only (nothing is inside by more than all of itself), containment only
    assert duplicates(w.boxes, w.scores, NMS_IOU, 1.0).tolist() == [
        i in greedy(w.boxes, w.scores, NMS_IOU, 1.0) for i in range(len(w))]
    assert duplicates(w.boxes, w.scores, 1.0, NMS_INSIDE).tolist() == [
        i in greedy(w.boxes, w.scores, 1.0, NMS_INSIDE) for i in range(len(w))]


def test_a_small_window_inside_a_large_one_is_suppressed() -> None:
    # a 64-px window inside a 128-px one: IoU 0.25, under the IoU rule, all of it inside
    b = np.array([[0, 0, 128, 128], [32, 32, 96, 96], [200, 0, 264, 64]], np.int32)
    assert duplicates(b, np.array([0.9, 0.8, 0.7]), NMS_IOU, NMS_INSIDE).tolist() == [True, False, True]
    assert duplicates(b, np.array([0.9, 0.8, 0.7]), NMS_IOU).tolist() == [True, True, True]
    # the larger window scored lower: less than half of it lies inside the small one, it stays
    assert duplicates(b, np.array([0.8, 0.9, 0.7]), NMS_IOU, NMS_INSIDE).tolist() == [True, True, True]
    with pytest.raises(ValueError, match="2 scores"):
        duplicates(b, np.array([0.1, 0.2]), NMS_IOU, NMS_INSIDE)


def test_many_windows_are_suppressed_as_few_are() -> None:
    """Above DENSE_DUPLICATES boxes the suppression goes one kept box at a time: the same rows
    kept, containment included."""
    rng = np.random.default_rng(3)
    n = DENSE_DUPLICATES + 200
    xy = rng.integers(0, 600, (n, 2))
    size = rng.choice([48, 64, 96, 128, 192], n)
    b = np.c_[xy, xy + size[:, None]].astype(np.int32)
    s = rng.random(n)
    many = duplicates(b, s, NMS_IOU, NMS_INSIDE)
    # the first DENSE_DUPLICATES ranked boxes decide among themselves as the dense path does
    top = np.argsort(-s, kind="stable")[:DENSE_DUPLICATES]
    dense = duplicates(b[top], s[top], NMS_IOU, NMS_INSIDE)
    assert many[top].tolist() == dense.tolist()
    assert 0 < many.sum() < n


def test_nms_stage_tells_of_a_new_picture_size() -> None:
    from fastdet.video.state import FrameState

    calls: list[bool] = []
    stage = NmsStage(calls.append)
    for shape in [(40, 60), (40, 60), (50, 60)]:
        s = FrameState(np.zeros((*shape, 3), np.uint8))
        s.windows = Detections(np.array([[0, 0, 20, 20], [2, 0, 22, 20]], np.int32), np.array([0.9, 0.8], np.float32))
        out = stage(s)
        assert len(out.boxes) == 1 and out.heatmap is None
    assert calls == [True, False]


def _frames(data: Path, n: int) -> list[np.ndarray]:
    with FrameReader(str(data / "videos" / "test_small1.mp4"), 40, n) as r:
        return [f for _, f, _ in r]


def test_the_pipelines_nms_boxes_are_its_windows_after_suppression(data: Path) -> None:
    """On real frames: the boxes before the tracker are nms_boxes of the frame's positive
    windows; with neither tracker nor refinement nor plausibility rules they are the output;
    the heat map gives other boxes (the test can tell the two apart)."""
    frames = _frames(data, 12)
    cfg = PipelineConfig(boxes="nms", oncoming=False)
    vd = VideoDetector(config=cfg)
    assert vd.stage(NmsStage) is not None and vd.stage(HeatStage) is None
    track = vd.stage(TrackStage)
    assert isinstance(track, TrackStage) and not track.split
    bare = VideoDetector(config=PipelineConfig(boxes="nms", oncoming=False, plausible=None).without(
        "tracker", "refine"))
    heat = VideoDetector(config=PipelineConfig(oncoming=False).without("tracker", "refine"))
    n_found = differ = 0
    for f in frames:
        vd.update(f)
        want = nms_boxes(vd.debug.windows)
        np.testing.assert_array_equal(vd.debug.boxes.boxes, want.boxes)
        assert vd.debug.heat.size == 0
        out = bare.update(f)
        want = nms_boxes(bare.debug.windows)
        np.testing.assert_array_equal(out.boxes, want.boxes)
        np.testing.assert_array_equal(out.scores, want.scores)
        n_found += len(out)
        h = heat.update(f)
        differ += len(h) != len(out) or not np.array_equal(h.boxes, out.boxes)
    assert n_found > 0 and differ > 0


def test_the_box_formation_is_the_configs_else_the_models_record(tmp_path: Path) -> None:
    model = load_model()
    nms = offset(model, 0.0, metadata={BOXES_KEY: "nms"}).save(tmp_path / "nms.npz")
    bad = offset(model, 0.0, metadata={BOXES_KEY: "blobs"}).save(tmp_path / "bad.npz")
    assert VideoDetector(config=PipelineConfig(model=str(nms))).stage(NmsStage) is not None
    assert VideoDetector(config=PipelineConfig(model=str(nms), boxes="heat")).stage(HeatStage) is not None
    assert VideoDetector(config=PipelineConfig()).stage(HeatStage) is not None
    assert VideoDetector(config=PipelineConfig(boxes="nms")).stage(NmsStage) is not None
    assert box_formation(PipelineConfig(), object()) == "heat"  # a detector with no model
    with pytest.raises(ModelError, match=BOXES_KEY):
        VideoDetector(config=PipelineConfig(model=str(bad))).stage(HeatStage)
    assert VideoDetector(config=PipelineConfig(model=str(bad), boxes="heat")).stage(HeatStage) is not None
    with pytest.raises(ValueError, match="boxes must be"):
        PipelineConfig(boxes="blobs")  # type: ignore[arg-type]
    # None is left out of the dict: the default config keeps its digest
    assert "boxes" not in PipelineConfig().to_dict()
    assert PipelineConfig.from_dict(PipelineConfig(boxes="nms").to_dict()).boxes == "nms"


def test_the_oncoming_model_runs_unless_the_main_model_records_otherwise(tmp_path: Path) -> None:
    from fastdet.video.detector import ONCOMING_KEY, make_detector

    model = load_model()
    own = offset(model, 0.0, metadata={ONCOMING_KEY: False}).save(tmp_path / "own.npz")
    bad = offset(model, 0.0, metadata={ONCOMING_KEY: "no"}).save(tmp_path / "bad.npz")
    assert make_detector(PipelineConfig()).oncoming_model is not None
    assert make_detector(PipelineConfig(model=str(own))).oncoming_model is None
    assert VideoDetector(config=PipelineConfig(model=str(own))).detector.oncoming_model is None
    # a named oncoming model runs whatever the record says; --no-oncoming leaves it out either way
    named = make_detector(PipelineConfig(model=str(own), oncoming=str(ONCOMING_MODEL_PATH)))
    assert named.oncoming_model is not None
    assert make_detector(PipelineConfig(oncoming=False)).oncoming_model is None
    with pytest.raises(ModelError, match=ONCOMING_KEY):
        make_detector(PipelineConfig(model=str(bad)))
    assert make_detector(PipelineConfig(model=str(bad), oncoming=False)).oncoming_model is None


@st.composite
def component_windows(draw: st.DrawFn) -> Detections:
    """Windows of the main model, the oncoming model and components (a side-view one: 2:1)."""
    n = draw(st.integers(0, 40))
    xy = draw(st.lists(st.tuples(st.integers(0, 200), st.integers(0, 120)), min_size=n, max_size=n))
    size = draw(st.lists(st.sampled_from([48, 64, 96, 128]), min_size=n, max_size=n))
    scores = draw(st.lists(st.sampled_from([0.55, 0.6, 0.7, 0.8, 0.9, 0.99]), min_size=n, max_size=n))
    part = draw(st.lists(st.sampled_from([MAIN_PART, ONCOMING_PART, FIRST_COMPONENT_PART, FIRST_COMPONENT_PART + 1]),
                         min_size=n, max_size=n))
    b = np.array([[x, y, x + s, y + (s // 2 if p >= FIRST_COMPONENT_PART else s)]
                  for (x, y), s, p in zip(xy, size, part)], np.int32).reshape(-1, 4)
    return Detections(b, np.array(scores, np.float32), part=np.array(part, np.int8))


@settings(max_examples=200, deadline=None)
@given(component_windows())
def test_nms_boxes_keep_the_components_windows_and_drop_the_oncoming_ones(w: Detections) -> None:
    """The main model's and the components' windows compete in one suppression; the oncoming
    model's take no part."""
    got = nms_boxes(w)
    kept = np.flatnonzero(w.part != ONCOMING_PART)
    want = kept[greedy(w.boxes[kept], w.scores[kept], NMS_IOU)]
    np.testing.assert_array_equal(got.boxes, w.boxes[want])
    np.testing.assert_array_equal(got.scores, w.scores[want])


def test_a_side_window_is_a_box_and_competes_with_the_main_windows() -> None:
    b = np.array([[0, 0, 128, 64],  # side-view window alone: kept
                  [300, 0, 364, 64],  # main window
                  [302, 0, 366, 32],  # side-view window on it, scored lower: inside it by all its area
                  [500, 0, 628, 64],  # oncoming window alone: dropped
                  [700, 0, 764, 64],  # main window ...
                  [690, 0, 818, 64]],  # ... under a better side-view window: IoU 0.5
                 np.int32)
    s = np.array([0.7, 0.9, 0.8, 0.95, 0.6, 0.8], np.float32)
    part = np.array([FIRST_COMPONENT_PART, MAIN_PART, FIRST_COMPONENT_PART, ONCOMING_PART, MAIN_PART,
                     FIRST_COMPONENT_PART], np.int8)
    got = nms_boxes(Detections(b, s, part=part))
    np.testing.assert_array_equal(got.boxes, b[[0, 1, 5]])
    np.testing.assert_array_equal(got.scores, s[[0, 1, 5]])
    assert len(nms_boxes(Detections(b[[3]], s[[3]], part=part[[3]]))) == 0


def test_the_pipelines_nms_boxes_take_the_side_components_windows(data: Path, tmp_path: Path) -> None:
    """A model file carrying a side-view component: the pipeline searches with it, and its nms
    boxes are the suppression of the main model's and the component's windows, some of them the
    component's; a Detector of it is accepted, one with other components is not."""
    from fastdet.detect import Detector

    frames = _frames(data, 6)
    model = model_carrying_side(frames[0])
    path = offset(model, 0.0).save(tmp_path / "side.npz")
    bare = VideoDetector(config=PipelineConfig(model=str(path), boxes="nms", oncoming=False, plausible=None).without(
        "tracker", "refine", "guided"))
    assert bare.detector.components[0].config.window_height == 32  # type: ignore[attr-defined]
    n_side = 0
    for f in frames:
        out = bare.update(f)
        w = bare.debug.windows
        assert (w.part == FIRST_COMPONENT_PART).any()
        want = nms_boxes(w)
        np.testing.assert_array_equal(out.boxes, want.boxes)
        np.testing.assert_array_equal(out.scores, want.scores)
        side = w[w.part == FIRST_COMPONENT_PART]
        n_side += sum(any(np.array_equal(b, s) for s in side.boxes) for b in out.boxes)
    assert n_side > 0
    VideoDetector(Detector(model), PipelineConfig(oncoming=False))
    with pytest.raises(ValueError, match="components"):
        VideoDetector(Detector(model, components=[(model.side, Detector(model).search)]), PipelineConfig())

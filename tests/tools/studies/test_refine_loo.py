"""tools/studies/refine_loo.py: the keyframe vehicles a leave-one-camera-out regressor is fitted
on (the Udacity clips and the test images one camera), the pipeline's own boxes paired with
their vehicles, and the optional regressor it ships (fastdet/models/refine_cameras.npz): fitted without
test_small1, it tightens boxes about test_small1's vehicles."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fastdet.config.models import REFINE_MODEL_PATH
from fastdet.detections import Detections
from fastdet.eval.clips import annotated_clips
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import read_frames, read_frames_at
from fastdet.train.refine import JitterConfig, jitter_boxes, paired_iou
from fastdet.video.refine import RefineConfig, load_regressor, refine_boxes
from tools.studies.refine_loo import ClipRun, clip_vehicles, own_views, training_clips

CAMERAS = REFINE_MODEL_PATH.with_name("refine_cameras.npz")


def test_keyframe_clip_gives_only_its_keyframes_targets(data: Path) -> None:
    clip = next(c for c in annotated_clips() if c.name == "highway_640")
    gt, kf = clip.gt(), clip.keyframes()
    images = read_frames_at(clip.video, kf.tolist())
    run = ClipRun(clip, [], {int(f): {} for f in kf}, 360, images)
    got = clip_vehicles(run, 2)
    want = [f for f in np.unique(gt.frames[gt.consider]) if f in set(kf.tolist())]
    assert len(got) == len(want) > 0
    assert sum(len(b) for _, b, _ in got) == int((np.isin(gt.frames, kf) & gt.consider).sum())
    for frame, boxes, groups in got:
        assert frame.shape == (360, 640, 3) and len(boxes) == len(groups)
        assert np.all((groups >= 3000) & (groups < 4000))


def test_udacity_clips_and_test_images_are_one_camera() -> None:
    clips = ["boston_street", "highway_640", "motorcycle_highway", "test_small1", "test_video"]
    assert training_clips(clips, "test_small1") == (["boston_street", "highway_640", "motorcycle_highway"], False)
    assert training_clips(clips, "test_video") == (["boston_street", "highway_640", "motorcycle_highway"], False)
    assert training_clips(clips, "highway_640") == (
        ["boston_street", "motorcycle_highway", "test_small1", "test_video"], True)


def test_own_views_pair_the_pipeline_boxes_with_their_vehicles(data: Path) -> None:
    clip = next(c for c in annotated_clips() if c.name == "boston_street")
    gt, kf = clip.gt(), clip.keyframes()
    f = int(next(f for f in kf if ((gt.frames == f) & gt.consider).any()))
    t = gt.boxes[(gt.frames == f) & gt.consider].astype(np.float64)
    near = t[:1] + np.array([0.0, -10, 0, 0])  # a box a little too tall on the first vehicle
    far = np.array([[0.0, 0, 10, 10]])
    rec = {f: {"out": Detections(near.astype(np.int32), np.ones(1)),
               "boxes": Detections(np.concatenate([near, far]).astype(np.int32), np.ones(2))}}
    run = ClipRun(clip, [], rec, 450, read_frames_at(clip.video, [f]))
    (v,) = own_views(run, 0, 0.3, "both")  # the same box from both sources counts once
    np.testing.assert_array_equal(v.inputs, near)
    np.testing.assert_array_equal(v.targets, t[:1])
    assert v.group[0] == 1000 + gt.ids[(gt.frames == f) & gt.consider][0]
    assert own_views(run, 0, 0.3, "out")[0].inputs.shape == (1, 4)


@pytest.mark.skipif(not CAMERAS.exists(), reason="no refine_cameras.npz")
def test_cameras_regressor_never_saw_test_small1_and_tightens_its_boxes(data: Path) -> None:
    reg = load_regressor(CAMERAS)
    meta = reg.metadata
    assert "test_small1" not in meta["trained_on"] and meta["held_out_clip"] == "test_small1"
    assert set(meta["leave_one_clip_out"]) == {c.name for c in annotated_clips()}
    frames = read_frames(data / "videos" / "test_small1.mp4")
    gt = read_gt(data / "annotations" / "test_small1.gt.txt")
    rng = np.random.default_rng(0)
    before, after = [], []
    for f in np.unique(gt.frames[gt.consider])[::8]:
        for t in gt.boxes[(gt.frames == f) & gt.consider]:
            b = jitter_boxes(t, 6, rng, JitterConfig(shift=0.15, scale=(0.8, 1.25), min_iou=0.4))
            tt = np.repeat(t[None], len(b), 0)
            before.extend(paired_iou(b, tt))
            after.extend(paired_iou(refine_boxes(frames[f - 1], b, reg, RefineConfig(iterations=3)), tt))
    assert np.mean(after) > np.mean(before) + 0.02

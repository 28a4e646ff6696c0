"""tools/studies/refine_loo.py: the keyframe vehicles a leave-one-clip-out regressor is fitted
on, and the optional regressor it ships (fastdet/models/refine_cameras.npz): fitted without
test_small1, it tightens boxes about test_small1's vehicles."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fastdet.config.models import REFINE_MODEL_PATH
from fastdet.eval.clips import annotated_clips
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import read_frames
from fastdet.train.refine import JitterConfig, jitter_boxes, paired_iou
from fastdet.video.refine import RefineConfig, load_regressor, refine_boxes
from tools.studies.refine_loo import clip_vehicles

CAMERAS = REFINE_MODEL_PATH.with_name("refine_cameras.npz")


def test_keyframe_clip_gives_only_its_keyframes_targets(data: Path) -> None:
    clip = next(c for c in annotated_clips() if c.name == "highway_640")
    gt, kf = clip.gt(), clip.keyframes()
    got = clip_vehicles(clip, 2)
    want = [f for f in np.unique(gt.frames[gt.consider]) if f in set(kf.tolist())]
    assert len(got) == len(want) > 0
    assert sum(len(b) for _, b, _ in got) == int((np.isin(gt.frames, kf) & gt.consider).sum())
    for frame, boxes, groups in got:
        assert frame.shape == (360, 640, 3) and len(boxes) == len(groups)
        assert np.all((groups >= 3000) & (groups < 4000))


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

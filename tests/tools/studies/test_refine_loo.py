"""tools/studies/refine_loo.py: the keyframe vehicles a leave-one-camera-out regressor is fitted
on (the Udacity clips and the test images one camera), the pipeline's own boxes paired with
their vehicles, and the optional regressor it ships (fastdet/models/refine_cameras.npz): fitted without
test_small1, it tightens boxes about test_small1's vehicles; the cache of the unrefined runs (plain arrays,
no pickle) comes back whole and is redone when the configuration changes."""
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
from tools.studies.refine_loo import ClipRun, clip_vehicles, load_run, own_views, save_run, training_clips

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


def _run(seed: int) -> tuple[list, dict]:
    rng = np.random.default_rng(seed)

    def dets(n: int, **cols) -> Detections:
        xy = rng.integers(0, 300, (n, 2))
        return Detections(np.c_[xy, xy + rng.integers(8, 60, (n, 2))].astype(np.int32),
                          rng.random(n).astype(np.float32), **{k: f(n) for k, f in cols.items()})

    frames = [(f, dets(n, ids=lambda n: rng.integers(-1, 9, n))) for f, n in ((1, 2), (2, 0), (3, 4), (5, 1))]
    rec = {f: {"out": frames[i][1], "boxes": dets(i), "heat": rng.random((9, 16)), "horizon": h,
               "windows": dets(2 * i + 1, scale=lambda n: rng.random(n).astype(np.float32),
                               part=lambda n: rng.integers(0, 3, n).astype(np.int8))}
           for i, (f, h) in enumerate(((1, None), (3, 0.5531234567)))}
    return frames, rec


def _same_dets(a: Detections, b: Detections) -> bool:
    return all((getattr(a, c) is None and getattr(b, c) is None) or
               (getattr(a, c).dtype == getattr(b, c).dtype and np.array_equal(getattr(a, c), getattr(b, c)))
               for c in ("boxes", "scores", "scale", "part", "ids", "frames", "consider"))


def _same_run(got: tuple[list, dict], want: tuple[list, dict]) -> bool:
    (gf, gr), (wf, wr) = got, want
    return ([f for f, _ in gf] == [f for f, _ in wf] and all(_same_dets(a, b) for (_, a), (_, b) in zip(gf, wf))
            and list(gr) == list(wr)
            and all(all(_same_dets(gr[f][k], wr[f][k]) for k in ("out", "boxes", "windows"))
                    and np.array_equal(gr[f]["heat"], wr[f]["heat"]) and gr[f]["horizon"] == wr[f]["horizon"]
                    for f in wr))


def test_run_cache_is_plain_arrays_and_comes_back_whole(tmp_path: Path, capsys) -> None:
    frames, rec = _run(0)
    save_run(tmp_path / "r.npz", "abc", frames, rec, 270)
    with np.load(tmp_path / "r.npz", allow_pickle=False) as z:  # no object arrays in it
        assert all(z[k].dtype != object for k in z.files)
    key, f2, r2, rows = load_run(tmp_path / "r.npz")
    assert key == "abc" and rows == 270 and _same_run((f2, r2), (frames, rec))
    assert not list(tmp_path.glob("*.partial*"))
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    assert load_run(tmp_path / "bad.npz") is None
    assert "bad.npz: not a run cache this study can read" in capsys.readouterr().err
    with pytest.raises(ValueError, match="searched"):
        save_run(tmp_path / "s.npz", "abc", frames, {1: {**rec[1], "searched": []}}, 270)


def test_unrefined_run_reads_its_cache_and_ignores_old_pickles(tmp_path: Path, monkeypatch, capsys) -> None:
    import argparse
    import pickle
    from types import SimpleNamespace

    from tools.scripts.refine_model import add_feature_arguments
    from tools.studies import refine_loo
    from tools.studies.small_boxes import add_setting_arguments

    ap = argparse.ArgumentParser()
    add_feature_arguments(ap)
    add_setting_arguments(ap)
    a = ap.parse_args([])
    calls = []
    frames, rec = _run(1)

    def run_clip(clip, config):
        calls.append(clip.name)
        return frames, rec, 270, {}

    monkeypatch.setattr(refine_loo, "run_clip", run_clip)
    monkeypatch.setattr(refine_loo, "read_frames_at", lambda video, fnos, notify: {f: None for f in fnos})
    clip = SimpleNamespace(name="clipx", video=tmp_path / "clipx.mp4")
    (tmp_path / "unrefined_clipx.pkl").write_bytes(pickle.dumps({"key": "x", "frames": [], "rec": {}, "rows": 1}))
    first = refine_loo.unrefined_run(clip, a, tmp_path)
    assert calls == ["clipx"] and "unrefined_clipx.pkl is a pickle" in capsys.readouterr().err
    second = refine_loo.unrefined_run(clip, a, tmp_path)  # from the cache: the clip does not run again
    assert calls == ["clipx"] and capsys.readouterr().err == ""
    for run in (first, second):
        assert run.rows == 270 and sorted(run.images) == sorted(rec) and _same_run((run.frames, run.rec), (frames, rec))
    a.no_split = True  # another configuration: the clip runs again
    refine_loo.unrefined_run(clip, a, tmp_path)
    assert calls == ["clipx", "clipx"]

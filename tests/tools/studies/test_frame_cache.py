"""tools/studies/frame_cache.py: the boxes of every frame written and read back, frame by
frame and column by column, empty frames included."""
from __future__ import annotations

import numpy as np

from fastdet.detections import Detections
from tools.studies.frame_cache import load_frame_detections, save_frame_detections


def _frames(seed: int, ids: bool) -> list[Detections]:
    rng = np.random.default_rng(seed)
    out = []
    for n in (3, 0, 1, 0, 5):
        xy = rng.integers(0, 600, (n, 2))
        boxes = np.c_[xy, xy + rng.integers(8, 120, (n, 2))]
        out.append(Detections(boxes, rng.random(n).astype(np.float32), scale=rng.random(n).astype(np.float32),
                              part=rng.integers(0, 3, n), ids=rng.integers(-1, 9, n) if ids else None))
    return out


def _same(a: Detections, b: Detections) -> bool:
    return all((getattr(a, c) is None and getattr(b, c) is None) or
               (getattr(a, c).dtype == getattr(b, c).dtype and np.array_equal(getattr(a, c), getattr(b, c)))
               for c in ("boxes", "scores", "scale", "part", "ids", "frames", "consider"))


def test_frames_come_back_as_they_went_in(tmp_path):
    for seed, ids in ((0, False), (1, True)):
        frames = _frames(seed, ids)
        path = tmp_path / "sub" / f"c{seed}.npz"  # the folder is made
        save_frame_detections(path, frames)
        got = load_frame_detections(path)
        assert len(got) == len(frames) and all(_same(a, b) for a, b in zip(got, frames))
        assert (got[0].ids is None) == (not ids)
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["c0.npz", "c1.npz"]  # no temporary left
    save_frame_detections(tmp_path / "none.npz", [])
    assert load_frame_detections(tmp_path / "none.npz") == []

"""tools/studies/frame_cache.py: the boxes of every frame written and read back, frame by
frame and column by column, empty frames included; lists of boxes with different columns
packed into plain arrays under a prefix and unpacked."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.detections import Detections
from tools.studies.frame_cache import (
    load_frame_detections,
    pack_detections,
    save_frame_detections,
    unpack_detections,
)


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


def test_packed_lists_come_back_with_each_item_s_own_columns(tmp_path):
    items = _frames(2, True)[:2] + _frames(3, False) + [Detections(np.zeros((0, 4), np.int32))]
    items[1] = items[1].with_frames(np.zeros(0, np.int64))  # an empty item with a column the others lack
    arrays = {**pack_detections(items, "a."), **pack_detections([], "b."), **pack_detections(items[2:4], "c.")}
    np.savez(tmp_path / "p.npz", **arrays)
    with np.load(tmp_path / "p.npz", allow_pickle=False) as z:  # plain arrays only
        got = {k: z[k] for k in z.files}
    for prefix, want in (("a.", items), ("b.", []), ("c.", items[2:4])):
        back = unpack_detections(got, prefix)
        assert len(back) == len(want) and all(_same(x, y) for x, y in zip(back, want))
    assert unpack_detections(got, "a.")[1].frames is not None and unpack_detections(got, "a.")[0].frames is None
    with pytest.raises(ValueError, match="a.scores: items of dtypes float32, float64"):
        pack_detections([items[0], Detections(np.zeros((1, 4), np.int32), np.ones(1))], "a.")

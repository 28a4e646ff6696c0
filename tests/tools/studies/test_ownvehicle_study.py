"""tools/studies/ownvehicle_study.py --save: a run's boxes and per-frame debug written as
plain arrays (.npz, read with allow_pickle=False) and JSON, read back array for array; an old
pickle of the study is not read, one line says so."""
from __future__ import annotations

import json

import numpy as np

from fastdet.detections import Detections
from tests.tools.studies.test_frame_cache import _same
from tools.studies.ownvehicle_study import load_run, save_run


def _dets(rng: np.random.Generator, n: int, **cols) -> Detections:
    xy = rng.integers(0, 600, (n, 2))
    return Detections(np.c_[xy, xy + rng.integers(8, 90, (n, 2))].astype(np.int32),
                      rng.random(n).astype(np.float32), **cols)


def _run(seed: int) -> tuple[Detections, list[dict]]:
    rng = np.random.default_rng(seed)
    debug = []
    for fno, n in zip((1, 2, 5), (3, 0, 2)):
        grid = (4 + fno, 7)  # grids of different sizes come back with their own shape
        debug.append({"frame": fno, "heat_boxes": _dets(rng, n),
                      "windows": _dets(rng, 2 * n, scale=rng.random(2 * n).astype(np.float32),
                                       part=rng.integers(0, 3, 2 * n).astype(np.int8)),
                      "heat": rng.random(grid).astype(np.float32),
                      "labels": rng.integers(0, 3, grid).astype(np.int32)})
    preds = Detections.from_frames([(d["frame"], d["heat_boxes"]) for d in debug], source="clip")
    return preds, debug


def test_a_saved_run_comes_back_array_for_array_without_pickle(tmp_path, capsys):
    preds, debug = _run(0)
    path = save_run(tmp_path / "ov", "split", "clip", preds, debug, {"scores": {"F1": 0.5}, "cpu_ms_per_frame": 3.0})
    assert path == tmp_path / "ov" / "split_clip.npz"
    assert sorted(p.name for p in path.parent.iterdir()) == ["split_clip.json", "split_clip.npz"]  # no temporary
    with np.load(path, allow_pickle=False) as z:
        assert all(z[k].dtype != object for k in z.files)
    got_preds, got_debug = load_run(path)
    assert _same(got_preds, preds) and len(got_debug) == len(debug)
    for g, d in zip(got_debug, debug):
        assert g["frame"] == d["frame"]
        assert _same(g["heat_boxes"], d["heat_boxes"]) and _same(g["windows"], d["windows"])
        for k in ("heat", "labels"):
            assert g[k].dtype == d[k].dtype and np.array_equal(g[k], d[k])
    meta = json.loads((tmp_path / "ov" / "split_clip.json").read_text())
    assert meta == {"variant": "split", "clip": "clip", "frames": 3, "scores": {"F1": 0.5}, "cpu_ms_per_frame": 3.0}
    assert capsys.readouterr().err == ""


def test_an_old_pickle_is_not_read_and_one_line_says_so(tmp_path, capsys):
    (tmp_path / "own_clip.pkl").write_bytes(b"\x80\x04not read")
    preds, debug = _run(1)
    save_run(tmp_path, "own", "clip", preds, debug, {})
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "own_clip.pkl" in err and "not read" in err
    assert (tmp_path / "own_clip.pkl").read_bytes() == b"\x80\x04not read"  # left alone
    assert _same(load_run(tmp_path / "own_clip.npz")[0], preds)

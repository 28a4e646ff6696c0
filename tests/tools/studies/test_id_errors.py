"""tools/studies/id_errors.py: a tracked run's identity errors sorted by cause, on hand-made
timelines whose counts are worked out by hand."""
from __future__ import annotations

import numpy as np
import pytest

from fastdet.detections import Detections
from fastdet.eval.clips import AnnotatedClip
from tools.studies.id_errors import appearance, bhattacharyya, causes, colour_histogram, main, parse_set


def _gt(rows: list[tuple[int, int, list[int], int]]) -> Detections:
    """rows: (frame, id, [x1, y1, x2, y2], consider)."""
    return Detections(np.array([r[2] for r in rows], np.int32).reshape(-1, 4), np.ones(len(rows), np.float32),
                      frames=np.array([r[0] for r in rows], np.int64), ids=np.array([r[1] for r in rows], np.int64),
                      consider=np.array([r[3] for r in rows], bool))


def _pred(rows: list[tuple[int, int, list[int]]]) -> Detections:
    return Detections(np.array([r[2] for r in rows], np.int32).reshape(-1, 4), np.ones(len(rows), np.float32),
                      frames=np.array([r[0] for r in rows], np.int64), ids=np.array([r[1] for r in rows], np.int64))


A = [100, 100, 200, 150]  # vehicle 1's box on every frame
B = [400, 100, 500, 150]  # vehicle 2's


def test_causes_of_each_id_change():
    # vehicle 1 on frames 1-10, vehicle 2 on frames 1-10
    gt = _gt([(f, 1, A, 1) for f in range(1, 11)] + [(f, 2, B, 1) for f in range(1, 11)])
    pred = []
    # vehicle 1: missed on frame 1 (late), id 1 on 2-4, missed 5-6, id 3 (new) on 7-8, id 4 on 9-10 (switch)
    pred += [(f, 1, A) for f in (2, 3, 4)] + [(f, 3, A) for f in (7, 8)] + [(f, 4, A) for f in (9, 10)]
    # vehicle 2: id 2 on 1-3, missed 4, id 1 (it hit vehicle 1 before) on 5-9, missed 10 (end)
    pred += [(f, 2, B) for f in (1, 2, 3)] + [(f, 1, B) for f in (5, 6, 7, 8, 9)]
    # a duplicate of vehicle 2 on frame 1 and a box on nothing on frame 2
    pred += [(1, 7, [410, 100, 520, 150]), (2, 8, [700, 300, 760, 340])]
    c = causes(gt, _pred(pred))
    assert (c.late, c.gap, c.gaps, c.end, c.never) == (1, 3, 2, 1, 0)
    assert (c.new_after_gap, c.taken_after_gap, c.switch) == (1, 1, 1)
    assert c.ids_on_two == 1  # id 1 hit both vehicles
    assert (c.dup_fp, c.fp) == (1, 2)
    # IDF1's pairing: vehicle 2 <-> id 1 (5 hits), vehicle 1 <-> id 3 or 4 (2 hits): off-id hits are
    # vehicle 1's 7 hits less 2, and vehicle 2's 3 hits under id 2
    assert c.off_id_hits == 5 + 3
    assert len(c.events) == 3


def test_keyframes_only_and_ignore_regions():
    # keyframes 1, 5, 9; an ignore region where a box sits on frame 5
    gt = _gt([(f, 1, A, 1) for f in (1, 5, 9)] + [(5, 1000, B, 0)])
    pred = _pred([(1, 1, A), (3, 2, A), (5, 2, B), (9, 2, A)])  # frame 3 is not scored
    c = causes(gt, pred, keyframes=np.array([1, 5, 9]))
    assert (c.gap, c.gaps, c.fp) == (1, 1, 0)  # missed on keyframe 5; the box on the ignore region is dropped
    assert (c.new_after_gap, c.taken_after_gap, c.switch, c.off_id_hits) == (1, 0, 0, 1)
    # no scored frame missed between keyframes 5 and 9 (6-8 are not scored): a switch
    c = causes(gt, _pred([(1, 1, A), (5, 1, A), (7, 2, [0, 0, 9, 9]), (9, 2, A)]), keyframes=np.array([1, 5, 9]))
    assert (c.gap, c.new_after_gap, c.switch, c.fp) == (0, 0, 1, 0)


def test_parse_set():
    assert parse_set("hold_row=false, max_lost=10,output=filtered") == {"hold_row": False, "max_lost": 10,
                                                                         "output": "filtered"}
    with pytest.raises(ValueError):
        parse_set("no_such_field=1")
    with pytest.raises(ValueError):
        parse_set("min_hits=0")
    with pytest.raises(ValueError):
        parse_set("hold_row")


def test_bad_arguments_are_one_line_and_exit_2(tmp_path, capsys):
    assert main(["--data", str(tmp_path), "--clips", "all", "--set", "min_hits=0"]) == 2
    assert main(["--data", str(tmp_path), "--clips", "all", "--pred-dir", str(tmp_path), "--set", "max_lost=3"]) == 2
    assert main(["--data", str(tmp_path), "--clips", "all", "--variants", "original,no_such_variant"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and all(line.startswith("id_errors: ") for line in err)
    assert "no_such_variant" in err[2]


def _histogram_reference(crop: np.ndarray, kind: str) -> np.ndarray:
    """The histograms of ``colour_histogram``, one pixel at a time."""
    import cv2

    if kind.startswith("hue-sat"):
        hsv = cv2.cvtColor(crop, cv2.COLOR_BGR2HSV)
        h = np.zeros(32)
        for hue, sat, _ in hsv.reshape(-1, 3).tolist():
            h[min(hue * 8 // 180, 7) * 4 + sat * 4 // 256] += 1
    elif kind.startswith("rgb"):
        h = np.zeros(64)
        for b, g, r in crop.reshape(-1, 3).tolist():
            h[(r // 64) * 16 + (g // 64) * 4 + b // 64] += 1
    else:
        h = np.zeros(64)
        for b, g, r in crop.reshape(-1, 3).tolist():
            t = r + g + b + 3
            rr, gg = min(max((r + 1) / t, 0.2), 0.5), min(max((g + 1) / t, 0.2), 0.5)
            h[min(int((rr - 0.2) / 0.3 * 8), 7) * 8 + min(int((gg - 0.2) / 0.3 * 8), 7)] += 1
    return h / max(h.sum(), 1e-12)


@pytest.mark.parametrize("kind", ["hue-sat 8x4", "rgb 4x4x4", "rg-chroma 8x8"])
def test_colour_histogram_against_counting_pixels(kind):
    rng = np.random.default_rng(3)
    for shape in ((5, 7, 3), (12, 3, 3)):
        crop = rng.integers(0, 256, shape, dtype=np.uint8)
        np.testing.assert_allclose(colour_histogram(crop, kind), _histogram_reference(crop, kind), atol=1e-12)


def test_bhattacharyya():
    a, b = np.array([0.5, 0.5, 0.0]), np.array([0.0, 0.0, 1.0])
    assert bhattacharyya(a, a) == pytest.approx(0.0, abs=1e-7)
    assert bhattacharyya(a, b) == pytest.approx(1.0)
    assert bhattacharyya(a, np.array([0.5, 0.0, 0.5])) == pytest.approx(np.sqrt(0.5))


def test_appearance_tells_a_red_car_from_its_grey_neighbour(tmp_path):
    """A red box moving right 5 px a frame on a blocky grey-ish background (tests.media) and a
    still patch of background beside it, both annotated: the red car's histogram stays close
    to itself, and far from its neighbour's."""
    from tests.media import write_video

    (tmp_path / "videos").mkdir()
    (tmp_path / "annotations").mkdir()
    video = write_video(tmp_path / "videos" / "c.mp4", 12)
    lines = []
    for f in range(1, 13):
        x = (f - 1) * 5
        lines.append(f"{f},1,{x + 4},84,52,42,1,1,1")  # inside the red box (80-130, x-x+60)
        lines.append(f"{f},2,150,84,52,42,1,1,1")  # background beside it
    gt = tmp_path / "annotations" / "c.gt.txt"
    gt.write_text("\n".join(lines) + "\n")
    r = appearance(AnnotatedClip("c", video, gt))
    for kind in ("hue-sat 8x4", "rgb 4x4x4", "rg-chroma 8x8"):
        assert r[kind]["same_pairs"] > 0 and r[kind]["neighbour_pairs"] > 0
        assert r[kind]["same"] < 0.2, kind
        assert r[kind]["neighbours"] > 0.5, kind
        assert r[kind]["same_1"] <= r[kind]["same"]

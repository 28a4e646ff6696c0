"""The single-picture search: PictureSearch's bands cover the whole picture at every scale,
and fastdet.detect_picture gives the boxes `fastdet image` writes."""
from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from fastdet.config import PictureSearch
from fastdet.train.windows import dense_search


def test_bands_cover_every_row_at_every_scale():
    ps = PictureSearch()
    s = ps.search((720, 1280))
    scales = [b.scale for b in s.bands]
    assert scales[0] == pytest.approx(40 / 64) and 64 * scales[-1] <= 720
    assert all(b2 / b1 == pytest.approx(math.sqrt(2)) for b1, b2 in zip(scales, scales[1:]))
    assert all(b.y_start == 0 and b.y_stop == 720 and b.x_start == 0 for b in s.bands)
    assert s.reference_shape is None and s.border == 0 and s.cells_per_step == 2
    # the same bands as the placement-free search of fastdet.train.windows
    d = dense_search((720, 1280), steps=2, cells_per_step=2)
    assert [(b.scale, b.y_start, b.y_stop, b.x_stop) for b in d.bands] == \
        [(pytest.approx(b.scale), b.y_start, b.y_stop, b.x_stop) for b in s.bands]
    assert PictureSearch.from_dict(ps.to_dict()) == ps


@pytest.mark.parametrize("bad", [{"min_width": 0}, {"steps": 0}, {"nms_iou": 1.0}, {"nms_min_score": math.nan},
                                 {"max_height": 1.5}])
def test_bad_settings(bad):
    with pytest.raises(ValueError):
        PictureSearch(**bad)


def test_too_small_picture():
    with pytest.raises(ValueError, match="too small for the picture search"):
        PictureSearch().search((12, 12))


def test_detect_picture_is_what_image_writes(test_images, tmp_path):
    import fastdet
    from fastdet import cli

    img = cv2.imread(str(test_images[0]))
    d = fastdet.detect_picture(img)
    assert d.boxes.dtype == np.int32 and d.boxes.shape[1] == 4
    csv = tmp_path / "b.csv"
    assert cli.main(["image", str(test_images[0]), "--boxes", str(csv), "--no-progress"]) == 0
    rows = [ln.split(",") for ln in csv.read_text().splitlines()[1:]]
    assert [[int(v) for v in r[1:5]] for r in rows] == d.boxes.tolist()
    assert [float(r[5]) for r in rows] == pytest.approx(d.scores.tolist(), abs=1e-4)


def test_the_boxes_found_are_refined_by_the_video_regressor(test_images):
    """detect = the found boxes moved by the video's box regressor (fastdet.video.refine.refine
    with the picture search's RefineConfig); refine=None leaves them as found."""
    from fastdet.video.picture import PictureDetector
    from fastdet.video.refine import load_regressor, refine

    img = cv2.imread(str(test_images[0]))
    pd = PictureDetector(config=PictureSearch(verify=False))
    found = pd.boxes_from_windows(pd.windows(img))
    assert len(found) > 0
    want = refine(img, found, load_regressor(), PictureSearch().refine)
    got = pd.detect(img)
    assert got.boxes.tolist() == want.boxes.tolist() and got.boxes.tolist() != found.boxes.tolist()
    assert got.scores.tolist() == found.scores.tolist()
    plain = PictureDetector(config=PictureSearch(refine=None, verify=False)).detect(img)
    assert plain.boxes.tolist() == found.boxes.tolist()
    # RGB input: the same boxes
    assert pd.detect(np.ascontiguousarray(img[..., ::-1]), rgb=True).boxes.tolist() == got.boxes.tolist()


def test_refined_boxes_match_more_annotated_vehicles(data):
    """On human-labelled pictures of a camera the regressor never saw (the first of kitti_tiny,
    whose cars are wider than a square window), the refined boxes match more vehicles at IoU
    0.5 than the square windows found."""
    from fastdet.eval.matching import match_frame
    from fastdet.labels.kitti import read_kitti
    from fastdet.video.picture import PictureDetector

    pics = read_kitti(data / "frames" / "kitti_tiny")[:8]
    pd = PictureDetector(config=PictureSearch(verify=False))
    hits = {"found": 0, "refined": 0}
    for pic in pics:
        img = pic.load()
        found = pd.boxes_from_windows(pd.windows(img))
        for name, d in (("found", found), ("refined", pd.refine(img, found))):
            hit, _, _ = match_frame(np.asarray(d.boxes, np.float64), np.asarray(d.scores, np.float64),
                                    pic.targets, pic.ignores, 0.5)
            hits[name] += int(hit.sum())
    assert hits["refined"] > hits["found"], hits


def test_the_verifier_keeps_the_refined_boxes_it_scores_above_its_threshold(test_images):
    """detect = the refined boxes the bundled verifier scores above its threshold, scored by its
    decision value (the plain formula on its inputs); verify=False keeps every refined box."""
    from fastdet.detect.verifier import load_verifier
    from fastdet.video.picture import PictureDetector

    img = cv2.imread(str(test_images[3]))
    v = load_verifier()
    pd = PictureDetector()
    refined = PictureDetector(config=PictureSearch(verify=False)).detect(img)
    assert len(refined) > 0
    x = v.features(img, refined.boxes, refined.scores)
    dv = ((x - v.mean) / v.scale) @ v.coef + v.intercept
    keep = dv > v.threshold
    got = pd.detect(img)
    assert got.boxes.tolist() == refined.boxes[keep].tolist()
    np.testing.assert_allclose(got.scores, dv[keep], rtol=1e-5)


def test_no_refine_is_the_first_stage_alone(test_images, tmp_path):
    """``image --no-refine``: the windows above decision value 2 after NMS, as found (no
    refinement, no verifier); the verifier needs refined boxes."""
    from fastdet import cli
    from fastdet.config.picture import FIRST_STAGE_ONLY
    from fastdet.video.picture import PictureDetector

    img = cv2.imread(str(test_images[0]))
    want = PictureDetector(config=FIRST_STAGE_ONLY).detect(img)
    pd = PictureDetector(config=FIRST_STAGE_ONLY)
    assert want.boxes.tolist() == pd.boxes_from_windows(pd.windows(img)).boxes.tolist()
    assert (want.scores > 2).all()
    csv = tmp_path / "b.csv"
    assert cli.main(["image", str(test_images[0]), "--boxes", str(csv), "--no-refine", "--no-progress"]) == 0
    rows = [ln.split(",") for ln in csv.read_text().splitlines()[1:]]
    assert [[int(v) for v in r[1:5]] for r in rows] == want.boxes.tolist()
    with pytest.raises(ValueError, match="verify looks at refined boxes"):
        PictureSearch(refine=None)

"""The box regressor's and verifier's context crops (fastdet.detect.regressor.regions_crops and
its kernel, fastdet.detect._crop_kernels.area_crops) give exactly the pixels of the plain
reference (one box at a time, cv2.copyMakeBorder + cv2.resize: tests/reference.py), and the
single-picture path and the video's refinement give the same boxes and scores as with the
reference's features, on real pictures.

- the kernel against OpenCV's general INTER_AREA written out one float32 operation at a time
  (``ref_area_resize``) and against ``cv2.resize`` itself, on random regions (hypothesis);
- ``region_crops`` against ``ref_region_crops`` on random frames and boxes (inside, across the
  edge, wholly outside, tiny, larger than the frame), at 1 and 2 threads;
- ``detect_picture`` with the fast crops against the same call with the reference features
  (``ref_box_features`` patched in) on the six test images and frames of dawn_fog; the video's
  ``refine`` likewise.
"""
from __future__ import annotations

import cv2
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet.detect import regressor, verifier
from fastdet.detect._crop_kernels import area_crops
from fastdet.detect.regressor import REFINE_FEATURES, box_features, region_crops, regions_crops
from tests.reference import ref_area_resize, ref_box_features, ref_region_crops


def _image(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    """A random picture with some smooth parts (ties in the rounding are likelier there)."""
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    if rng.random() < 0.5:
        img = cv2.GaussianBlur(img, (5, 5), 1.5)
    if rng.random() < 0.3:
        img[: h // 2] = rng.integers(0, 256, 3, dtype=np.uint8)  # flat
    return np.ascontiguousarray(img)


def _kernel_crop(img: np.ndarray, g: tuple[int, ...], size: tuple[int, int]) -> np.ndarray:
    """One crop of geometry ``g`` by the kernel."""
    h, w = img.shape[:2]
    rows = img.reshape(h, w * 3)
    rows.flags.writeable = False
    sh, sw = g[1] - g[0], g[3] - g[2]
    out = np.zeros((1, *size, 3), np.uint8)
    area_crops(rows, np.array([g], np.int64), np.array([[1.0 / (size[1] / sw), 1.0 / (size[0] / sh)]]),
               np.zeros(1, np.int64), out)
    return out[0]


def _replicated(img: np.ndarray, g: tuple[int, ...]) -> np.ndarray:
    """The region of geometry ``g``, its pixels outside the clamp rectangle repeating its border."""
    y0, y1, x0, x1, ylo, yhi, xlo, xhi = g
    return np.ascontiguousarray(img[np.clip(np.arange(y0, y1), ylo, yhi)][:, np.clip(np.arange(x0, x1), xlo, xhi)])


def _geometry(rng: np.random.Generator, h: int, w: int, sh: int, sw: int) -> tuple[int, ...]:
    y0, x0 = int(rng.integers(-sh, h)), int(rng.integers(-sw, w))
    y1, x1 = y0 + sh, x0 + sw
    ylo, yhi = min(max(y0, 0), h - 1), min(max(y1 - 1, 0), h - 1)
    xlo, xhi = min(max(x0, 0), w - 1), min(max(x1 - 1, 0), w - 1)
    return y0, y1, x0, x1, ylo, yhi, xlo, xhi


def _general_path(sh: int, sw: int, dh: int, dw: int) -> bool:
    """OpenCV's general INTER_AREA path: shrinking, the scales not both whole numbers."""
    return regressor._area_scales((sh, sw), (dh, dw)) is not None


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dh=st.integers(1, 6), dw=st.integers(1, 6), fy=st.floats(1.0, 5.0),
       fx=st.floats(1.0, 5.0))
def test_kernel_is_opencvs_area_shrink_one_operation_at_a_time(seed, dh, dw, fy, fx):
    rng = np.random.default_rng(seed)
    sh, sw = max(dh, round(dh * fy)), max(dw, round(dw * fx))
    while not _general_path(sh, sw, dh, dw):
        sw += 1
    img = _image(rng, int(rng.integers(1, 40)), int(rng.integers(1, 40)))
    g = _geometry(rng, img.shape[0], img.shape[1], sh, sw)
    region = _replicated(img, g)
    want = ref_area_resize(region, (dh, dw))
    np.testing.assert_array_equal(_kernel_crop(img, g, (dh, dw)), want)
    np.testing.assert_array_equal(cv2.resize(region, (dw, dh), interpolation=cv2.INTER_AREA), want)


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), out=st.sampled_from([(64, 64), (32, 48), (7, 5)]),
       fy=st.floats(1.0, 16.0), fx=st.floats(1.0, 16.0))
def test_kernel_is_cv2_resize_inter_area(seed, out, fy, fx):
    """Against OpenCV itself, at the crops' sizes: 64x64 windows from regions up to 16x."""
    rng = np.random.default_rng(seed)
    dh, dw = out
    sh, sw = max(dh, round(dh * fy)), max(dw, round(dw * fx))
    while not _general_path(sh, sw, dh, dw):
        sh += 1
    img = _image(rng, int(rng.integers(1, 300)), int(rng.integers(1, 300)))
    g = _geometry(rng, img.shape[0], img.shape[1], sh, sw)
    want = cv2.resize(_replicated(img, g), (dw, dh), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(_kernel_crop(img, g, (dh, dw)), want)


def test_scales_that_are_whole_numbers_go_to_opencv():
    """OpenCV rounds its integer-scale shrink otherwise (half up, not half to even): that
    path is cv2.resize's own (the kernel would give other pixels there)."""
    flat = np.zeros((2, 2, 3), np.uint8)
    flat[0, :, 1] = 116
    flat[1, :, 1] = 117  # the mean is 116.5
    assert cv2.resize(flat, (1, 1), interpolation=cv2.INTER_AREA)[0, 0, 1] != ref_area_resize(flat, (1, 1))[0, 0, 1]
    assert regressor._area_scales((128, 192), (64, 64)) is None  # OpenCV's integer path
    assert regressor._area_scales((64, 64), (64, 64)) is None  # a copy
    assert regressor._area_scales((63, 200), (64, 64)) is None  # enlarging: INTER_LINEAR
    assert regressor._area_scales((64, 100), (64, 64)) == (100 / 64, 1.0)


_size = st.one_of(st.floats(0, 900), st.floats(0, 1e12))
_coord = st.one_of(st.floats(-400, 1000, allow_nan=False), st.floats(-1e12, 1e12, allow_nan=False))


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), h=st.integers(1, 200), w=st.integers(1, 300),
       boxes=st.lists(st.tuples(_coord, _coord, _size, _size), min_size=0, max_size=12),
       context=st.sampled_from([0.5, 1.0, 1.5, 2.0, 3.7]), size=st.sampled_from([(64, 64), (16, 24)]))
def test_region_crops_are_the_references(seed, h, w, boxes, context, size):
    rng = np.random.default_rng(seed)
    img = _image(rng, h, w)
    b = np.array([(x, y, x + bw, y + bh) for x, y, bw, bh in boxes], np.float64).reshape(-1, 4)
    np.testing.assert_array_equal(region_crops(img, b, context, size), ref_region_crops(img, b, context, size))


@pytest.mark.parametrize("threads", [1, 2])
def test_region_crops_of_many_boxes_at_one_and_two_threads(threads):
    rng = np.random.default_rng(7)
    img = _image(rng, 720, 1280)
    x, y = rng.uniform(-200, 1300, 60), rng.uniform(-100, 700, 60)
    s = np.exp(rng.uniform(np.log(20), np.log(700), 60))
    b = np.stack([x, y, x + s * rng.uniform(0.6, 1.6, 60), y + s], axis=1)
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        got = regions_crops(img, b, (1.0, 1.5), (64, 64))
    finally:
        numba.set_num_threads(before)
    for k, c in enumerate((1.0, 1.5)):
        np.testing.assert_array_equal(got[k], ref_region_crops(img, b, c, (64, 64)))
    # read-only and non-contiguous frames give the same
    ro = img.copy()
    ro.flags.writeable = False
    np.testing.assert_array_equal(regions_crops(ro, b, (1.5,), (64, 64))[0], got[1])
    np.testing.assert_array_equal(regions_crops(np.asfortranarray(img), b, (1.5,), (64, 64))[0], got[1])


def test_bad_arguments():
    with pytest.raises(ValueError, match="finite"):
        region_crops(np.zeros((10, 10, 3), np.uint8), np.array([[0, 0, np.nan, 5]]), 1.0, (8, 8))
    with pytest.raises(ValueError, match="uint8"):
        region_crops(np.zeros((10, 10), np.uint8), np.array([[0, 0, 5, 5]]), 1.0, (8, 8))
    with pytest.raises(ValueError, match="positive"):
        region_crops(np.zeros((10, 10, 3), np.uint8), np.array([[0, 0, 5, 5]]), 1.0, (0, 8))


def _pictures(data) -> list[np.ndarray]:
    paths = sorted((data / "test_images").glob("*.jpg"))
    fog = sorted((data / "frames" / "dawn_fog" / "images").glob("*.jpg"))
    paths += fog[:: max(1, len(fog) // 4)][:4]
    return [cv2.imread(str(p)) for p in paths]


def _reference_features(monkeypatch) -> None:
    """The second stage's features as first written (ref_box_features), wherever they are used."""
    monkeypatch.setattr(regressor, "box_features", ref_box_features)
    monkeypatch.setattr(verifier, "box_features", ref_box_features)


def test_detect_picture_gives_the_boxes_and_scores_of_the_reference_crops(data, monkeypatch):
    """The whole single-picture path (first stage, refinement, verifier) on real pictures: the
    same boxes and scores as with the reference's one-box-at-a-time crops and features."""
    from fastdet.video.picture import PictureDetector

    pics = _pictures(data)
    det = PictureDetector()
    found = [det.boxes_from_windows(det.windows(p)) for p in pics]
    assert sum(len(f) for f in found) > 50  # enough boxes to mean something
    new = [det.second_stage(p, f) for p, f in zip(pics, found)]
    # the features themselves: bit for bit
    for p, f in zip(pics, found):
        np.testing.assert_array_equal(box_features(p, f.boxes, REFINE_FEATURES, (1.0, 1.5)),
                                      ref_box_features(p, f.boxes, REFINE_FEATURES, (1.0, 1.5)))
    _reference_features(monkeypatch)
    old = [det.second_stage(p, f) for p, f in zip(pics, found)]
    assert sum(len(o) for o in old) > 0
    for a, b in zip(new, old):
        np.testing.assert_array_equal(a.boxes, b.boxes)
        np.testing.assert_allclose(a.scores, b.scores, rtol=0, atol=1e-9)


def test_video_refinement_gives_the_boxes_of_the_reference_crops(data, monkeypatch):
    from fastdet.detections import Detections
    from fastdet.video.refine import load_regressor, refine

    pics = _pictures(data)[:4]
    reg = load_regressor()
    rng = np.random.default_rng(3)
    dets = []
    for _ in pics:
        x, y = rng.uniform(0, 1100, 5), rng.uniform(300, 600, 5)
        s = rng.uniform(30, 300, 5)
        dets.append(Detections(np.stack([x, y, x + s, y + 0.8 * s], axis=1).astype(np.int32),
                               np.ones(5, np.float32)))
    new = [refine(p, d, reg) for p, d in zip(pics, dets)]
    _reference_features(monkeypatch)
    old = [refine(p, d, reg) for p, d in zip(pics, dets)]
    for a, b in zip(new, old):
        np.testing.assert_array_equal(a.boxes, b.boxes)

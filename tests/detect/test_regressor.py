"""fastdet.detect.regressor: the box regressor's offsets, features and file."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings

from fastdet.config.models import REFINE_MODEL_PATH, REFINE_UDACITY_MODEL_PATH
from fastdet.detect.regressor import (
    BoxRegressor,
    box_features,
    carried_regressor,
    carrying,
    decode_offsets,
    encode_offsets,
    load_regressor,
    region_crops,
)
from fastdet.errors import FastdetError, ModelError
from fastdet.video.refine import refine_boxes
from tests.video.test_refine import SMALL, _frame, boxes, small_offset  # the refinement tests' helpers


@settings(max_examples=200, deadline=None)
@given(boxes(), boxes())
def test_encode_decode_round_trip(b: np.ndarray, g: np.ndarray) -> None:
    t = encode_offsets(b, g)
    np.testing.assert_allclose(decode_offsets(b, t), g, rtol=1e-9, atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(boxes(), small_offset, small_offset, small_offset, small_offset)
def test_decode_encode_round_trip(b: np.ndarray, tx: float, ty: float, tw: float, th: float) -> None:
    t = np.array([[tx, ty, tw, th]])
    np.testing.assert_allclose(encode_offsets(b, decode_offsets(b, t)), t, rtol=1e-7, atol=1e-7)


def test_offsets_known_values() -> None:
    b = np.array([[0, 0, 100, 50]])
    g = np.array([[10, -5, 210, 45]])  # centre +60 x, -5 y; twice as wide, as high
    np.testing.assert_allclose(encode_offsets(b, g), [[0.6, -0.1, math.log(2), 0.0]])
    np.testing.assert_allclose(decode_offsets(b, np.zeros((1, 4))), b)
    with pytest.raises(ValueError):
        encode_offsets(np.array([[0, 0, 0, 10]]), g)


def test_region_crops_and_features() -> None:
    frame = _frame()
    b = np.array([[0, 0, 64, 64], [-30, -30, 30, 30], [100, 50, 140, 90]], np.float64)
    crops = region_crops(frame, b, 1.0, (64, 64))
    assert crops.shape == (3, 64, 64, 3) and crops.dtype == np.uint8
    np.testing.assert_array_equal(crops[0], frame[:64, :64])  # same size: the pixels themselves
    assert crops[1][0, 0].tolist() == frame[0, 0].tolist()  # replicated border
    x = box_features(frame, b, SMALL, (1.0, 2.0))
    assert x.shape == (3, 2 * SMALL.n_features)
    assert box_features(frame, np.zeros((0, 4)), SMALL, (1.0,)).shape == (0, SMALL.n_features)


def test_save_load_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    reg0 = BoxRegressor.zero(SMALL, (1.0, 1.5))
    reg = BoxRegressor(SMALL, (1.0, 1.5), rng.normal(size=reg0.coef.shape), rng.normal(size=4),
                       rng.normal(size=reg0.n_features), rng.uniform(0.5, 2, reg0.n_features), metadata={"note": "x"})
    p = reg.save(tmp_path / "r.npz")
    back = load_regressor(p)
    assert back.config == SMALL and back.contexts == (1.0, 1.5) and back.metadata["note"] == "x"
    for k in ("coef", "intercept", "mean", "scale"):
        np.testing.assert_array_equal(getattr(back, k), getattr(reg, k))
    frame = _frame(3)
    bx = np.array([[20.0, 30.0, 120.0, 90.0]])
    np.testing.assert_array_equal(refine_boxes(frame, bx, back), refine_boxes(frame, bx, reg))
    assert not list(tmp_path.glob(".*partial*"))


def test_a_model_file_carries_its_cameras_regressor(tmp_path: Path) -> None:
    """adapt's model file holds the camera's regressor beside the main model's arrays: loaded
    back it refines exactly as the regressor did, the pipeline takes it when no regressor file
    is named (a named one wins), and the main model's own arrays are untouched."""
    from fastdet.batch.settings import checked_settings
    from fastdet.config import PipelineConfig
    from fastdet.model import load_model
    from fastdet.video.picture import PictureDetector
    from fastdet.video.refine import regressor_for

    rng = np.random.default_rng(2)
    n = BoxRegressor.zero(SMALL, (1.0, 1.5)).n_features
    reg = BoxRegressor(SMALL, (1.0, 1.5), rng.normal(size=(4, n)), rng.normal(size=4), rng.normal(size=n),
                       rng.uniform(0.5, 2, n), metadata={"note": "camera"})
    plain = load_model()
    assert carried_regressor(plain) is None
    path = carrying(plain, reg).save(tmp_path / "cam.npz")
    back = load_model(path)
    for k in ("coef", "mean", "scale"):
        np.testing.assert_array_equal(getattr(back, k), getattr(plain, k))
    assert back.intercept == plain.intercept
    got = carried_regressor(back, str(path))
    assert got is not None and got.metadata["note"] == "camera"
    frame = _frame(4)
    bx = np.array([[20.0, 30.0, 120.0, 90.0], [5.0, 5.0, 60.0, 50.0]])
    np.testing.assert_array_equal(refine_boxes(frame, bx, got), refine_boxes(frame, bx, reg))
    # saved again (as adapt moves it by an offset), it still carries it
    again = load_model(back.save(tmp_path / "again.npz"))
    np.testing.assert_array_equal(carried_regressor(again).coef, reg.coef)
    # the pipeline's choice: the named file, else the carried one, else the bundled one
    np.testing.assert_array_equal(regressor_for(str(path), None).coef, reg.coef)
    assert regressor_for(str(path), str(REFINE_MODEL_PATH)).metadata.get("note") != "camera"
    assert regressor_for(None, None).metadata.get("note") != "camera"
    np.testing.assert_array_equal(PictureDetector(str(path)).regressor.coef, reg.coef)
    # a VideoDetector refines with it too, the main model file read once (by its detector)
    import fastdet.detect.detector as detector_mod
    import fastdet.video.refine as refine_mod
    from fastdet.video import VideoDetector

    reads: list[str] = []

    def counted(p: object = None, *a: object, **k: object) -> object:
        reads.append(str(p))
        return load_model(p, *a, **k)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(detector_mod, "load_model", counted)
        mp.setattr(refine_mod, "load_model", counted)
        vd = VideoDetector(config=PipelineConfig(model=str(path)))
        assert vd.detector.model.metadata == back.metadata
    assert vd.refiner is not None
    np.testing.assert_array_equal(vd.refiner.coef, reg.coef)
    assert reads.count(str(path)) == 1, reads
    assert VideoDetector(config=PipelineConfig(model=str(path), refine_model=str(REFINE_MODEL_PATH))
                         ).refiner.metadata.get("note") != "camera"
    # a batch keeps it (no regressor file of its own: the model file's hash covers it), its
    # settings made with the main model file read once
    cam = PipelineConfig(model=str(path))
    reads.clear()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(detector_mod, "load_model", counted)
        mp.setattr(refine_mod, "load_model", counted)
        settings = checked_settings(cam)
    assert settings.pipeline.refine_model is None
    assert reads.count(str(path)) == 1, reads
    assert checked_settings(PipelineConfig()).pipeline.refine_model == str(REFINE_MODEL_PATH.resolve())
    assert checked_settings(PipelineConfig(model=str(path), refine_model=str(REFINE_MODEL_PATH))
                            ).pipeline.refine_model == str(REFINE_MODEL_PATH.resolve())


def test_a_carried_regressor_that_is_not_one_is_one_line(tmp_path: Path) -> None:
    from fastdet.model import CARRIED, load_model, write_npz

    plain = load_model()
    arrays = {"coef": plain.coef, "intercept": np.float64(plain.intercept), "mean": plain.mean, "scale": plain.scale}
    meta = {**plain.metadata, "format_version": 1}
    p = write_npz(tmp_path / "m1.npz", arrays, {**meta, "regressor": "yes"})
    with pytest.raises(ModelError, match="'regressor' must be a JSON object"):
        load_model(p)
    p = write_npz(tmp_path / "m2.npz", arrays, {**meta, "regressor": {"kind": "box_regressor"}})
    with pytest.raises(ModelError, match="missing array"):
        load_model(p)
    zeros = {v: np.zeros((4, 3)) for v in CARRIED.values()}
    p = write_npz(tmp_path / "m3.npz", {**arrays, **zeros}, {**meta, "regressor": {"kind": "no", "format_version": 1}})
    with pytest.raises(ModelError, match="not a box regressor") as e:
        carried_regressor(load_model(p), str(p))
    assert str(p) in str(e.value) and "\n" not in str(e.value)


def test_cascade_save_load_and_stage_choice(tmp_path: Path) -> None:
    """A cascade's file holds its stages along a leading axis; a one-stage regressor's file
    keeps the two-dimensional arrays it always had; step i uses stage i, the last one after."""
    rng = np.random.default_rng(1)
    n = SMALL.n_features
    stages = [BoxRegressor(SMALL, (1.0,), rng.normal(size=(4, n)), rng.normal(size=4), rng.normal(size=n),
                           rng.uniform(0.5, 2, n)) for _ in range(3)]
    cas = BoxRegressor.stack(stages, metadata={"note": "c"})
    assert cas.n_stages == 3 and stages[0].n_stages == 1
    back = load_regressor(cas.save(tmp_path / "c.npz"))
    assert back.n_stages == 3 and back.metadata["stages"] == 3 and back.metadata["note"] == "c"
    with np.load(tmp_path / "c.npz") as z:
        assert z["coef"].shape == (3, 4, n) and z["scale"].shape == (3, n)
    with np.load(stages[0].save(tmp_path / "one.npz")) as z:
        assert z["coef"].shape == (4, n) and z["intercept"].shape == (4,)
    x = rng.normal(size=(5, n))
    for i in range(5):
        np.testing.assert_array_equal(back.predict_features(x, stage=i), stages[min(i, 2)].predict_features(x))
    with pytest.raises(ModelError):
        BoxRegressor(SMALL, (1.0,), np.zeros((2, 4, n)), np.zeros((3, 4)), np.zeros((2, n)), np.ones((2, n)))


def _write_npz(path: Path, **arrays: np.ndarray) -> Path:
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)
    return path


def test_bad_files_raise_clear_errors(tmp_path: Path) -> None:
    good = BoxRegressor.zero(SMALL).save(tmp_path / "good.npz")
    with np.load(good, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(arrays["metadata"].tobytes().decode())

    def blob(m: dict) -> np.ndarray:
        return np.frombuffer(json.dumps(m).encode(), np.uint8)

    cases = {
        "missing.npz": None,
        "text.npz": "not a zip",
        "empty.npz": "",
        "truncated.npz": good.read_bytes()[:200],
        "noarray.npz": {k: v for k, v in arrays.items() if k != "coef"},
        "pickled.npz": {**arrays, "coef": np.array([object()], dtype=object)},
        "badjson.npz": {**arrays, "metadata": np.frombuffer(b"{nope", np.uint8)},
        "version.npz": {**arrays, "metadata": blob({**meta, "format_version": 99})},
        "kind.npz": {**arrays, "metadata": blob({**meta, "kind": "classifier"})},
        "shape.npz": {**arrays, "coef": arrays["coef"][:, :-1]},
        "nan.npz": {**arrays, "scale": np.full_like(arrays["scale"], np.nan)},
    }
    for name, content in cases.items():
        p = tmp_path / name
        if isinstance(content, dict):
            _write_npz(p, **content)
        elif isinstance(content, str):
            p.write_text(content)
        elif isinstance(content, bytes):
            p.write_bytes(content)
        with pytest.raises(ModelError) as ei:
            load_regressor(p)
        assert isinstance(ei.value, FastdetError)
        assert str(p) in str(ei.value) and "\n" not in str(ei.value), name
    with pytest.raises(ModelError, match="not a file"):
        load_regressor(tmp_path)


@pytest.mark.parametrize("path", [REFINE_MODEL_PATH, REFINE_UDACITY_MODEL_PATH])
def test_the_bundled_regressors_predict_the_ridge_of_their_crops(path: Path, tmp_path: Path) -> None:
    """The bundled regressors' offsets are the ridge of the context crops' features, computed
    here by hand; written again, they predict the same."""
    reg = load_regressor(path)
    assert "size_inputs" not in reg.metadata
    assert reg.n_features == len(reg.contexts) * reg.config.n_features
    frame = _frame(4, (360, 640))
    b = np.array([[100.0, 150.0, 160.0, 190.0], [300.0, 120.0, 420.0, 220.0]])
    x = box_features(frame, b, reg.config, reg.contexts)
    want = ((x - reg.mean[0]) / reg.scale[0]) @ reg.coef[0].T + reg.intercept[0]
    np.testing.assert_array_equal(reg.predict(frame, b), want)
    again = load_regressor(reg.save(tmp_path / "again.npz"))
    assert "size_inputs" not in again.metadata
    np.testing.assert_array_equal(again.predict(frame, b), want)


def test_a_file_written_with_size_inputs_is_refused_in_one_line(tmp_path: Path) -> None:
    """Size inputs (the box's size among the regressor's inputs) were deleted: a file that
    lists them (with their extra columns) is refused, naming them; an empty list is none."""
    rng = np.random.default_rng(5)
    n = SMALL.n_features + 2
    good = BoxRegressor.zero(SMALL, (1.5,)).save(tmp_path / "good.npz")
    with np.load(good, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(arrays["metadata"].tobytes().decode())
    sized = {"coef": rng.normal(size=(4, n)), "intercept": rng.normal(size=4), "mean": rng.normal(size=n),
             "scale": rng.uniform(0.5, 2, n),
             "metadata": np.frombuffer(json.dumps({**meta, "size_inputs": ["log_width", "width<60"]}).encode(),
                                       np.uint8)}
    p = _write_npz(tmp_path / "sized.npz", **sized)
    with pytest.raises(ModelError, match="size inputs") as ei:
        load_regressor(p)
    assert str(p) in str(ei.value) and "\n" not in str(ei.value)
    arrays["metadata"] = np.frombuffer(json.dumps({**meta, "size_inputs": []}).encode(), np.uint8)
    assert load_regressor(_write_npz(tmp_path / "none.npz", **arrays)).n_features == SMALL.n_features
    with pytest.raises(ValueError, match="differ"):
        BoxRegressor.stack([BoxRegressor.zero(SMALL, (1.0,)), BoxRegressor.zero(SMALL, (1.5,))])

"""Model files: round trip, and every way a file can be wrong gives a clear ModelError."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fastdet.config import FeatureConfig
from fastdet.errors import ModelError
from fastdet.model import FORMAT_VERSION, Model, load_model
from tests.reference import sklearn_pair

CFG = FeatureConfig(color_space="LUV", hog_channels=(0,), orientations=6, spatial_size=8, hist_bins=8)


def _model(seed=0, classifier="linearsvc"):
    rng = np.random.default_rng(seed)
    n = CFG.n_features
    return Model(CFG, rng.normal(size=n), 0.3, rng.normal(size=n) * 10, rng.uniform(0.5, 3, n),
                 classifier=classifier, metadata={"training": {"note": "test"}})


def _crops(n=5, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (n, 64, 64, 3), dtype=np.uint8)


def test_round_trip(tmp_path):
    m = _model()
    path = m.save(tmp_path / "m.npz")
    back = load_model(path)
    assert back.config == CFG and back.classifier == "linearsvc"
    np.testing.assert_array_equal(back.coef, m.coef)
    assert back.metadata["format_version"] == FORMAT_VERSION
    assert back.metadata["training"]["note"] == "test"
    np.testing.assert_array_equal(back.decision_function(_crops()), m.decision_function(_crops()))


def test_decision_function_matches_sklearn_and_folding():
    from fastdet.features import extract_features

    m = _model()
    x = extract_features(_crops(), CFG)
    scaler, clf = sklearn_pair(m)
    ref = clf.decision_function(scaler.transform(x))
    np.testing.assert_allclose(m.decision_function(_crops()), ref, rtol=0, atol=1e-9)
    w, b = m.folded()
    np.testing.assert_allclose(x @ w + b, ref, rtol=1e-9, atol=1e-8)
    assert set(np.unique(m.predict(_crops()))) <= {0, 1}
    with pytest.raises(AttributeError, match="logistic"):
        m.predict_proba(_crops())
    p = _model(classifier="logreg").predict_proba(_crops())
    assert p.shape == (5, 2) and np.allclose(p.sum(1), 1)


def test_empty_file(tmp_path):
    p = tmp_path / "m.npz"
    p.write_bytes(b"")
    with pytest.raises(ModelError, match="empty file"):
        load_model(p)


def test_missing_file(tmp_path):
    with pytest.raises(ModelError, match="not found"):
        load_model(tmp_path / "nope.npz")


def test_not_npz(tmp_path):
    p = tmp_path / "m.npz"
    p.write_text("hello")
    with pytest.raises(ModelError, match="not an .npz"):
        load_model(p)


def test_truncated(tmp_path):
    p = _model().save(tmp_path / "m.npz")
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(ModelError, match="npz"):
        load_model(p)


def _rewrite(tmp_path, **override):
    m = _model()
    meta = {"format_version": FORMAT_VERSION, "feature_config": CFG.to_dict(), "classifier": "linearsvc"}
    arrays = dict(coef=m.coef, intercept=np.float64(0.1), mean=m.mean, scale=m.scale)
    meta.update(override.pop("meta", {}))
    arrays.update(override)
    arrays.setdefault("metadata", np.frombuffer(json.dumps(meta).encode(), np.uint8))
    p = tmp_path / "m.npz"
    np.savez(p, **{k: v for k, v in arrays.items() if v is not None})
    return p


def test_wrong_version(tmp_path):
    with pytest.raises(ModelError, match="format version 99"):
        load_model(_rewrite(tmp_path, meta={"format_version": 99}))


def test_missing_array(tmp_path):
    with pytest.raises(ModelError, match="missing array.*scale"):
        load_model(_rewrite(tmp_path, scale=None))


def test_config_mismatch_with_weights(tmp_path):
    cfg = FeatureConfig(color_space="LUV", hog_channels=(0, 1), orientations=6, spatial_size=8, hist_bins=8)
    with pytest.raises(ModelError, match="feature config mismatch"):
        load_model(_rewrite(tmp_path, meta={"feature_config": cfg.to_dict()}))


def test_config_mismatch_with_expected(tmp_path):
    p = _model().save(tmp_path / "m.npz")
    with pytest.raises(ModelError, match="feature config mismatch"):
        load_model(p, expected_config=FeatureConfig())


def test_bad_feature_config(tmp_path):
    with pytest.raises(ModelError, match="bad feature configuration"):
        load_model(_rewrite(tmp_path, meta={"feature_config": {"color_space": "XYZ"}}))


def test_pickled_object_array_is_refused(tmp_path):
    p = _rewrite(tmp_path, metadata=np.array([{"evil": 1}], dtype=object))
    with pytest.raises(ModelError, match="pickled object array"):
        load_model(p)


def test_bundled_default_model_loads():
    m = load_model()
    assert m.config == FeatureConfig()
    assert m.metadata["training"]["sequence_split"]["accuracy"] > 0.98


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_intercept_is_refused(tmp_path, bad):
    with pytest.raises(ModelError, match="'intercept' holds values that are not finite"):
        load_model(_rewrite(tmp_path, intercept=np.float64(bad)))


def test_non_finite_weight_is_refused(tmp_path):
    coef = _model().coef.copy()
    coef[3] = np.nan
    with pytest.raises(ModelError, match="'coef' holds values that are not finite"):
        load_model(_rewrite(tmp_path, coef=coef))


def _replace_member(path, name, data: bytes):
    import zipfile
    with zipfile.ZipFile(path) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist()}
    members[name] = data
    with zipfile.ZipFile(path, "w") as zf:
        for k, v in members.items():
            zf.writestr(k, v)
    return path


PICKLE_NONE = b"\x80\x04\x95\x05\x00\x00\x00\x00\x00\x00\x00N."


@pytest.mark.parametrize("data", [np.random.default_rng(0).bytes(500), PICKLE_NONE], ids=["random-bytes", "pickle"])
def test_array_member_that_is_not_npy_is_one_line(tmp_path, data):
    p = _replace_member(_rewrite(tmp_path), "coef.npy", data)
    with pytest.raises(ModelError, match="'coef' is not a valid .npy array"):
        load_model(p)


def test_npy_header_claiming_a_huge_shape_allocates_nothing(tmp_path):
    import io
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (10**12,)})
    p = _replace_member(_rewrite(tmp_path), "coef.npy", buf.getvalue() + b"\0" * 64)
    with pytest.raises(ModelError, match=r"claims shape \(1000000000000,\)"):
        load_model(p)


# ---- issue 34, items 11 and 15: absurd model files refused before allocating -------------


def _compressed_member(tmp_path, name, shape, dtype="<f8"):
    """A model whose ``name`` array declares ``shape`` of zeros (deflated: a few MB on disk)."""
    import io
    import zipfile
    p = _rewrite(tmp_path)
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": dtype, "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(p) as zf:
        members = {i.filename: zf.read(i) for i in zf.infolist() if i.filename != f"{name}.npy"}
    with zipfile.ZipFile(p, "w", zipfile.ZIP_DEFLATED) as zf:
        for k, v in members.items():
            zf.writestr(k, v)
        with zf.open(f"{name}.npy", "w", force_zip64=True) as fh:
            fh.write(header.getvalue())
            zero = bytes(2**22)
            n = int(np.prod(shape)) * np.dtype(dtype).itemsize
            for _ in range(n // len(zero)):
                fh.write(zero)
            fh.write(bytes(n % len(zero)))
    return p


def test_array_declaring_a_huge_shape_of_zeros_is_refused_before_it_is_read(tmp_path):
    import tracemalloc
    p = _compressed_member(tmp_path, "coef", (40_000_000,))  # 320 MB of zeros, deflated to 0.3 MB
    assert p.stat().st_size < 2**20
    tracemalloc.start()
    with pytest.raises(ModelError, match=r"'coef' declares shape \(40000000,\).*more than the 64 MB"):
        load_model(p)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 50 * 2**20


def test_huge_metadata_is_refused(tmp_path):
    p = _compressed_member(tmp_path, "metadata", (20 * 2**20,), "|u1")
    with pytest.raises(ModelError, match="'metadata' declares shape .* more than the 16 MB"):
        load_model(p)


def test_metadata_nested_too_deeply_is_one_line(tmp_path):
    meta = np.frombuffer(b"[" * 200_000, np.uint8)
    with pytest.raises(ModelError, match="metadata is not valid JSON"):
        load_model(_rewrite(tmp_path, metadata=meta))


@pytest.mark.parametrize("change, msg", [
    ({"orientations": 16.5}, "orientations must be of type int, got float 16.5"),
    ({"window": 64.0}, "window must be of type int, got float 64.0"),
    ({"pixels_per_cell": True}, "pixels_per_cell must be of type int"),
    ({"hog_channels": [0, "1"]}, "hog_channels must be of type"),
    ({"pixels_per_cell": 1, "cells_per_block": 64}, "values per pixel and channel"),
    ({"window": 100000, "pixels_per_cell": 1000}, "window and window_height must be in"),
])
def test_feature_config_of_wrong_type_or_absurd_size_is_one_line(tmp_path, change, msg):
    cfg = {**CFG.to_dict(), **change}
    with pytest.raises(ModelError, match=f"bad feature configuration in metadata: .*{msg}"):
        load_model(_rewrite(tmp_path, meta={"feature_config": cfg}))


def test_feature_count_is_bounded():
    from fastdet.config.features import MAX_FEATURES
    with pytest.raises(ValueError, match=f"features per window .at most {MAX_FEATURES}"):
        FeatureConfig(pixels_per_cell=4, cells_per_block=4, orientations=16, window=256)


@pytest.mark.parametrize("name, value, msg", [
    ("scale", 1e-310, "'scale' holds values outside"),
    ("coef", 1e308, "'coef' holds 1e\\+308"),
    ("mean", -1e300, "'mean' holds 1e\\+300"),
])
def test_absurd_values_are_refused_on_load(tmp_path, name, value, msg):
    m = _model()
    arr = getattr(m, name).copy()
    arr[3] = value
    with pytest.raises(ModelError, match=msg):
        load_model(_rewrite(tmp_path, **{name: arr}))


def test_absurd_intercept_and_folded_weights_are_refused(tmp_path):
    with pytest.raises(ModelError, match="'intercept' is 1e\\+200"):
        load_model(_rewrite(tmp_path, intercept=np.float64(1e200)))
    m = _model()
    coef, scale = m.coef.copy(), m.scale.copy()
    coef[0], scale[0] = 1e6, 1e-9
    with pytest.raises(ModelError, match="'coef' / 'scale' reaches"):
        load_model(_rewrite(tmp_path, coef=coef, scale=scale))


# ---- a camera's side-view component carried in the model file (Model.side) --------------

SIDE_CFG = FeatureConfig(color_space="LUV", hog_channels=(0,), orientations=6, spatial_size=8, hist_bins=8,
                         window_height=32)


def _side(seed=1, classifier="linearsvc", **kw):
    rng = np.random.default_rng(seed)
    n = SIDE_CFG.n_features
    return Model(SIDE_CFG, rng.normal(size=n), -0.7, rng.normal(size=n) * 10, rng.uniform(0.5, 3, n),
                 classifier=classifier, metadata={"fit": {"vehicles": 21}, "note": "side"}, **kw)


def _with_side(seed=0):
    from dataclasses import replace
    return replace(_model(seed), side=_side(seed + 1))


def test_a_side_view_component_round_trips(tmp_path):
    """Every array, the config, the classifier and the metadata of the component come back; the
    main model's too; a second save of the loaded model gives the same component again."""
    m = _with_side()
    back = load_model(m.save(tmp_path / "m.npz"))
    assert back.side is not None and back.regressor is None and back.side.side is None
    for a, b in ((back, m), (back.side, m.side)):
        assert a.config == b.config and a.classifier == b.classifier and a.intercept == b.intercept
        for name in ("coef", "mean", "scale"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert back.side.config == SIDE_CFG and back.side.config.win_h == 32
    assert back.side.metadata["fit"] == {"vehicles": 21} and back.side.metadata["note"] == "side"
    assert back.metadata["training"]["note"] == "test"
    crops = np.random.default_rng(3).integers(0, 256, (4, 32, 64, 3), dtype=np.uint8)
    np.testing.assert_array_equal(back.side.decision_function(crops), m.side.decision_function(crops))
    again = load_model(back.save(tmp_path / "again.npz"))
    assert again.side is not None and again.side.metadata == back.side.metadata
    np.testing.assert_array_equal(again.side.coef, m.side.coef)
    assert again.side.intercept == m.side.intercept


def test_a_model_without_its_side_component_saves_none(tmp_path):
    """A loaded model's metadata holds the component's record; the model without the component
    (side=None) writes neither it nor its arrays."""
    import zipfile
    from dataclasses import replace

    back = load_model(_with_side().save(tmp_path / "m.npz"))
    assert "side" in back.metadata
    p = replace(back, side=None).save(tmp_path / "plain.npz")
    with zipfile.ZipFile(p) as zf:
        assert not any(n.startswith("side_") for n in zf.namelist())
    plain = load_model(p)
    assert plain.side is None and "side" not in plain.metadata


def test_side_view_components_that_cannot_be_are_refused():
    from dataclasses import replace

    main = _model()
    with pytest.raises(ModelError, match="wide-window"):
        replace(main, side=_model(1))  # square windows
    with pytest.raises(ModelError, match="carries nothing"):
        replace(main, side=replace(_side(), side=_side(2)))  # a component of its own
    reg = ({k: np.zeros(2) for k in ("coef", "intercept", "mean", "scale")}, {"note": "reg"})
    with pytest.raises(ModelError, match="carries nothing"):
        replace(main, side=_side(regressor=reg))
    with pytest.raises(ModelError, match="carries nothing"):
        replace(main, side="side.npz")  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="logreg model, the main model a linearsvc"):
        replace(main, side=_side(classifier="logreg"))
    other = replace(SIDE_CFG, orientations=9)  # other features: it could not share the band's HOG
    n = other.n_features
    with pytest.raises(ModelError, match="main model's features"):
        replace(main, side=Model(other, np.zeros(n), 0.0, np.zeros(n), np.ones(n)))
    assert replace(main, side=_side()).side is not None


_GOOD = object()


def _side_file(tmp_path, side_meta=_GOOD, **arrays):
    """A model file with a side-view component whose metadata / arrays are overridden."""
    m, s = _model(), _side()
    meta = {"format_version": FORMAT_VERSION, "feature_config": CFG.to_dict(), "classifier": "linearsvc",
            "side": {"feature_config": SIDE_CFG.to_dict(), "classifier": "linearsvc"} if side_meta is _GOOD
            else side_meta}
    out = dict(coef=m.coef, intercept=np.float64(0.1), mean=m.mean, scale=m.scale, side_coef=s.coef,
               side_intercept=np.float64(s.intercept), side_mean=s.mean, side_scale=s.scale)
    out.update(arrays)
    out["metadata"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    p = tmp_path / "m.npz"
    np.savez(p, **{k: v for k, v in out.items() if v is not None})
    return p


@pytest.mark.parametrize("bad", [["a"], "side", 3, None])
def test_side_metadata_that_is_not_an_object_is_a_model_error(tmp_path, bad):
    with pytest.raises(ModelError, match="metadata 'side' must be a JSON object"):
        load_model(_side_file(tmp_path, side_meta=bad))


@pytest.mark.parametrize("side_meta, arrays, msg", [
    ({}, {}, "bad feature configuration of the side-view component"),
    ({"feature_config": {"color_space": "XYZ"}}, {}, "bad feature configuration of the side-view component"),
    (_GOOD, {"side_scale": None}, "missing array.*side_scale"),
    (_GOOD, {"side_intercept": np.zeros(2)}, "'side_intercept' must be a scalar"),
    (_GOOD, {"side_coef": np.zeros(5)}, "side-view component: feature config mismatch"),
    (_GOOD, {"side_intercept": np.float64(np.nan)}, "side_intercept"),
    ({"feature_config": CFG.to_dict(), "classifier": "linearsvc"}, {"side_coef": _model().coef,
     "side_mean": _model().mean, "side_scale": _model().scale}, "side-view component must be a wide-window"),
    ({"feature_config": SIDE_CFG.to_dict(), "classifier": "logreg"}, {}, "logreg model, the main model a linearsvc"),
])
def test_a_broken_side_component_is_a_model_error(tmp_path, side_meta, arrays, msg):
    with pytest.raises(ModelError, match=msg):
        load_model(_side_file(tmp_path, side_meta=side_meta, **arrays))


def test_a_side_file_loads(tmp_path):
    """The file _side_file writes without overrides loads: the cases above fail for their own reason."""
    m = load_model(_side_file(tmp_path))
    assert m.side is not None and m.side.config == SIDE_CFG
    np.testing.assert_array_equal(m.side.coef, _side().coef)

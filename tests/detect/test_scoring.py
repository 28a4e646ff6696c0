"""The dense-scoring kernels (fastdet.detect.scoring) against a plain loop over windows and
products, on random inputs of every shape the kernels branch on (8-, 4- and 1-window runs,
parallel chunks of a row), and their checks. Real frames: tests/detect/test_detector.py."""
from __future__ import annotations

import re

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fastdet._numba import REASSOC
from fastdet.detect import _score_kernels
from fastdet.detect.scoring import dense_scores, hist_weight_integral, weight_table
from tests.reference import loop_dense_scores


@st.composite
def band_case(draw):
    k = draw(st.integers(1, 24))
    nby, nbx = draw(st.integers(1, 4)), draw(st.integers(1, 4))
    step = draw(st.integers(1, 3))
    ny, nx = draw(st.integers(0, 4)), draw(st.integers(0, 45))
    cell = draw(st.sampled_from([2, 4, 8]))
    sp_off = draw(st.sampled_from([d for d in (1, 2, 4, 8) if cell % d == 0]))
    spatial, hist = draw(st.booleans()), draw(st.booleans())
    hist_step = draw(st.sampled_from([d for d in (1, 2, 4, 8) if cell % d == 0]))
    win_h, win_w = hist_step * draw(st.integers(1, 8)), hist_step * draw(st.integers(1, 8))
    extra = draw(st.tuples(st.integers(0, 3), st.integers(0, 3)))
    return {"k": k, "nby": nby, "nbx": nbx, "step": step, "ny": ny, "nx": nx, "cell": cell, "sp_off": sp_off,
            "spatial": spatial, "hist": hist, "hist_step": hist_step, "win_h": win_h, "win_w": win_w, "extra": extra,
            "parallel": draw(st.booleans()), "seed": draw(st.integers(0, 2**32 - 1))}


def _arrays(c):
    rng = np.random.default_rng(c["seed"])
    k, step, cell, sp_off = c["k"], c["step"], c["cell"], c["sp_off"]
    ny, nx, (er, ec) = c["ny"], c["nx"], c["extra"]
    rows = max(ny - 1, 0) * step + c["nby"] + er
    cols = (max(nx - 1, 0) * step + c["nbx"]) * k + ec * k
    a = {"block_rows": rng.normal(size=(rows, cols)), "w_hog": rng.normal(size=(c["nby"], c["nbx"] * k))}
    if c["spatial"]:
        sh, sw = rng.integers(1, 5, 2)
        a["w_sp"] = rng.normal(size=(sh, sw * 3))
        a["spat_rows"] = rng.normal(size=(max(ny - 1, 0) * step * cell // sp_off + sh + er,
                                          max(nx - 1, 0) * step * cell // sp_off * 3 + sw * 3 + ec))
    if c["hist"]:
        g = c["hist_step"]
        a["integ"] = rng.normal(size=((max(ny - 1, 0) * step * cell + c["win_h"]) // g + 1 + er,
                                      (max(nx - 1, 0) * step * cell + c["win_w"]) // g + 1 + ec))
    return a, float(rng.normal())


@settings(max_examples=150, deadline=None)
@given(band_case())
def test_dense_scores_equal_a_plain_loop(c):
    a, bias = _arrays(c)
    out = np.full((c["ny"], c["nx"]), np.nan)
    got = dense_scores(a["block_rows"], a["w_hog"], c["k"], out, step=c["step"], cell=c["cell"], win_h=c["win_h"],
                       win_w=c["win_w"], bias=bias, spat_rows=a.get("spat_rows"), w_sp=a.get("w_sp"),
                       sp_off=c["sp_off"], integ=a.get("integ"), hist_step=c["hist_step"], parallel=c["parallel"])
    assert got is out
    ref = loop_dense_scores(a["block_rows"], a["w_hog"], c["k"], c["ny"], c["nx"], c["step"], c["cell"],
                            c["win_h"], c["win_w"], bias, a.get("spat_rows"), a.get("w_sp"), c["sp_off"],
                            a.get("integ"), c["hist_step"])
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-11)


def test_serial_and_parallel_agree_bit_for_bit():
    """``parallel=True`` runs the same kernel on rows spread over threads: the same bits."""
    rng = np.random.default_rng(5)
    k, nx, ny = 192, 81, 5  # a default band's row: 10 runs of 8 windows and one
    rows, w = rng.random((2 * (ny - 1) + 7, (2 * (nx - 1) + 7) * k)), rng.normal(size=(7, 7 * k))
    a = dense_scores(rows, w, k, np.empty((ny, nx)), step=2, cell=8, win_h=64, win_w=64, bias=0.5)
    before = numba.get_num_threads()
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    try:
        b = dense_scores(rows, w, k, np.empty((ny, nx)), step=2, cell=8, win_h=64, win_w=64, bias=0.5,
                         parallel=True)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(a, loop_dense_scores(rows, w, k, ny, nx, 2, 8, 64, 64, 0.5), rtol=0, atol=1e-10)


def test_checks():
    rows, w, out = np.zeros((7, 7 * 12)), np.zeros((7, 7 * 12)), np.empty((1, 1))
    kw = {"step": 2, "cell": 8, "win_h": 64, "win_w": 64}
    dense_scores(rows, w, 12, out, **kw)
    with pytest.raises(ValueError, match="too small"):
        dense_scores(rows, w, 12, np.empty((1, 2)), **kw)
    with pytest.raises(ValueError, match="too small"):
        dense_scores(rows[:6], w, 12, out, **kw)
    with pytest.raises(ValueError, match="float64"):
        dense_scores(rows.astype(np.float32), w, 12, out, **kw)
    with pytest.raises(ValueError, match="C-contiguous"):
        dense_scores(np.zeros((7, 7 * 24))[:, ::2], w, 12, out, **kw)
    with pytest.raises(ValueError, match="whole blocks"):
        dense_scores(rows, w, 11, out, **kw)
    with pytest.raises(ValueError, match="go together"):
        dense_scores(rows, w, 12, out, spat_rows=np.zeros((32, 96)), **kw)
    with pytest.raises(ValueError, match="too small"):
        dense_scores(rows, w, 12, out, spat_rows=np.zeros((31, 96)), w_sp=np.zeros((32, 96)), sp_off=2, **kw)
    with pytest.raises(ValueError, match="too small"):
        dense_scores(rows, w, 12, out, integ=np.zeros((64, 65)), **kw)
    with pytest.raises(ValueError, match="too small"):
        dense_scores(rows, w, 12, out, integ=np.zeros((9, 8)), hist_step=8, **kw)
    with pytest.raises(ValueError, match="divide"):
        dense_scores(rows, w, 12, out, integ=np.zeros((9, 9)), hist_step=3, **kw)
    dense_scores(rows, w, 12, out, integ=np.zeros((9, 9)), hist_step=8, **kw)
    dense_scores(rows, w, 12, np.empty((0, 5)), **kw)  # no windows: nothing to check against


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 40), st.integers(0, 40), st.integers(1, 4), st.sampled_from([1, 2, 3, 8]),
       st.sampled_from([(32, 3), (16, 4), (256, 0)]), st.integers(0, 2**32 - 1))
def test_hist_weight_integral_is_the_cumulative_sum(h, w, c, g, bins_shift, seed):
    bins, shift = bins_shift
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (h, w, c), dtype=np.uint8)
    wh = rng.normal(size=(c, bins))
    per_pixel = sum(wh[ch, img[:, :, ch] >> shift] for ch in range(c)) + np.zeros((h, w))
    ref = np.zeros((h + 1, w + 1))
    ref[1:, 1:] = per_pixel.cumsum(0).cumsum(1)
    got = hist_weight_integral(img, weight_table(wh, shift), g)
    assert got.shape == (h // g + 1, w // g + 1)
    np.testing.assert_allclose(got, ref[::g, ::g][: h // g + 1, : w // g + 1], rtol=0, atol=1e-9)


def test_hist_weight_integral_checks():
    img, w = np.zeros((8, 8, 3), np.uint8), np.zeros((3, 32))
    with pytest.raises(ValueError, match="bins"):
        weight_table(np.ascontiguousarray(w[:, :16]), 3)
    t = weight_table(w, 3)
    assert t.shape == (3, 256) and t[1, 37] == w[1, 37 >> 3]
    with pytest.raises(ValueError, match="table"):
        hist_weight_integral(img, t[:2], 8)
    with pytest.raises(ValueError, match="step"):
        hist_weight_integral(img, t, 0)
    with pytest.raises(ValueError, match="out must be"):
        hist_weight_integral(img, t, 8, out=np.empty((9, 9)))


def _cpu_flags() -> set[str]:
    try:
        with open("/proc/cpuinfo") as f:
            return set(next(line for line in f if line.startswith("flags")).split(":")[1].split())
    except (OSError, StopIteration):
        return set()


@pytest.mark.skipif(not {"avx2", "fma"} <= _cpu_flags(), reason="an x86-64 CPU with AVX2 and FMA")
def test_inner_loop_is_packed_fma_without_gathers():
    """The kernel compiles to packed fused multiply-adds on ymm/zmm registers and no
    gathers (the per-window loop it replaced indexed with a possibly negative offset and got
    vgatherqpd). Compiled afresh: Numba does not show the assembly of cached code."""
    fresh = numba.njit(**dict(REASSOC, cache=False))(_score_kernels.dense_scores.py_func)
    rows, w = np.zeros((7, 7 * 12)), np.zeros((7, 7 * 12))
    fresh(rows, w, 12, np.zeros((0, 0)), np.zeros((0, 0)), 1, np.zeros((1, 1)), 1, 64, 64, 8, 2, 0.0, 0, 1,
          np.empty((1, 1)))
    asm = fresh.inspect_asm(fresh.signatures[0])
    assert re.search(r"vfmadd\d+pd\s+[^\n]*%[yz]mm", asm), "no packed FMA in the scoring kernel"
    assert "gather" not in asm

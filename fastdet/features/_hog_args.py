"""Argument checks of the HOG wrappers (:mod:`fastdet.features._hog`): positive integers,
(rows, cols) pairs, block-norm names, the working float dtype of an image, and the cell /
block grid an image of a shape gives."""
from __future__ import annotations

import operator
from collections.abc import Sequence

import numpy as np

from . import _hog_kernels as _k

#: block normalisation names (as scikit-image spells them) -> the kernels' codes
BLOCK_NORMS = {
    "L1": _k.NORM_L1,
    "L1-sqrt": _k.NORM_L1_SQRT,
    "L2": _k.NORM_L2,
    "L2-Hys": _k.NORM_L2_HYS,
}


def _positive_int(value, name: str) -> int:
    try:
        v = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be a positive integer, got {value!r}") from None
    if v < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return v


def _pair(value, name: str) -> tuple[int, int]:
    """An int or a 2-sequence of ints, each >= 1."""
    if isinstance(value, (Sequence, np.ndarray)) and not isinstance(value, str):
        if len(value) != 2:
            raise ValueError(f"{name} must be an int or a pair of ints, got {value!r}")
        return _positive_int(value[0], name), _positive_int(value[1], name)
    v = _positive_int(value, name)
    return v, v


def _block_norm_code(block_norm) -> int:
    try:
        return BLOCK_NORMS[block_norm]
    except (KeyError, TypeError):
        raise ValueError(
            f"block_norm must be one of {sorted(BLOCK_NORMS)}, got {block_norm!r}"
        ) from None


def _hog_params(orientations, pixels_per_cell, cells_per_block, block_norm) -> tuple[int, tuple, tuple, int]:
    """The HOG parameters every public function takes, checked: ``(orientations,
    (cell rows, cell cols), (block rows, block cols), block-norm code)``."""
    return (_positive_int(orientations, "orientations"), _pair(pixels_per_cell, "pixels_per_cell"),
            _pair(cells_per_block, "cells_per_block"), _block_norm_code(block_norm))


def _float_dtype(dtype: np.dtype) -> type:
    """skimage's working float type: float16/float32 -> float32, everything else -> float64."""
    if dtype.kind not in "biuf":
        raise ValueError(f"image must have a real numeric dtype, got {dtype}")
    return np.float32 if dtype in (np.float16, np.float32) else np.float64


def _as_array(image, name: str = "image") -> np.ndarray:
    try:
        arr = np.asarray(image)
    except Exception as exc:  # noqa: BLE001 - any conversion failure is a bad argument
        raise ValueError(f"{name} must be array-like: {exc}") from None
    if arr.size == 0:
        raise ValueError(f"{name} is empty (shape {arr.shape})")
    return arr


def _geometry(shape, ppc, cpb, name="image"):
    """Cells and blocks that fit in an image of spatial ``shape`` (skimage's rules)."""
    n_cells = (shape[0] // ppc[0], shape[1] // ppc[1])
    n_blocks = (n_cells[0] - cpb[0] + 1, n_cells[1] - cpb[1] + 1)
    if n_blocks[0] <= 0 or n_blocks[1] <= 0:
        raise ValueError(
            f"The input image is too small given the values of pixels_per_cell and "
            f"cells_per_block: {name} of shape {tuple(shape)}, pixels_per_cell={ppc} and "
            f"cells_per_block={cpb} need at least {cpb[0] * ppc[0]} rows and "
            f"{cpb[1] * ppc[1]} columns"
        )
    return n_cells, n_blocks


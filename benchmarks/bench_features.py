"""Feature extraction for the training crops: fastdet's batched kernels vs the plain
reference (skimage HOG per channel + cv2.resize + np.histogram, one crop at a time).

Run::

    python -m pytest benchmarks/bench_features.py --benchmark-only

fastdet extracts all 17,760 crops of ``vehicles/`` and ``non-vehicles/`` per call, at 1 and
2 Numba threads; the reference, at about 5 ms a crop, runs on 500 of them and
``extra_info["ms_per_crop"]`` gives both per crop, the figure to compare.
"""
from __future__ import annotations

import numba
import numpy as np
import pytest

from fastdet.config import FeatureConfig
from fastdet.features import extract_features
from fastdet.train.dataset import load_crops
from tests.reference import crop_features

CFG = FeatureConfig()


@pytest.fixture(scope="module")
def crops(data):
    return load_crops(data).images


@pytest.mark.parametrize("threads", [1, 2])
def test_fastdet_all_crops(benchmark, crops, threads):
    benchmark.group = "features: all 17,760 training crops"
    numba.set_num_threads(threads)
    extract_features(crops[:64], CFG)  # compile / load outside the timing
    try:
        benchmark.pedantic(extract_features, args=(crops, CFG), rounds=3, iterations=1)
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    benchmark.extra_info["crops"] = len(crops)
    benchmark.extra_info["ms_per_crop"] = benchmark.stats.stats.min * 1000 / len(crops)


def test_reference_500_crops(benchmark, crops):
    benchmark.group = "features: all 17,760 training crops"
    sample = crops[:: len(crops) // 500][:500]
    benchmark.pedantic(lambda: np.stack([crop_features(c, CFG) for c in sample]), rounds=1, iterations=1)
    benchmark.extra_info["crops"] = len(sample)
    benchmark.extra_info["ms_per_crop"] = benchmark.stats.stats.min * 1000 / len(sample)

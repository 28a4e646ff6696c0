"""Choose the feature configuration and C by held-out crop accuracy (run by hand).

For each FeatureConfig in the grid, features are extracted once (plus mirrored copies for
the training parts); each classifier/C is fitted on the training part of the leak-free
sequence split and of the random split and scored on the test parts. Prints a markdown
table. Usage: ``python -m tools.studies.select_model [--quick]``.
"""
from __future__ import annotations

import argparse
import itertools
import time

import numpy as np

from fastdet.config import FeatureConfig
from fastdet.data import data_dir
from fastdet.train.dataset import load_crops, random_split, sequence_split
from fastdet.train.fit import features_in_chunks, fit_classifier, metrics


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--configs", default="default", help="comma list of presets")
    ap.add_argument("--C", default="1e-4,3e-4,1e-3,3e-3,1e-2")
    ap.add_argument("--classifiers", default="logreg,linearsvc")
    ap.add_argument("--seeds", default="0")
    args = ap.parse_args()
    presets = {
        "default": FeatureConfig(),
        "luv": FeatureConfig(color_space="LUV"),
        "ycrcb12": FeatureConfig(orientations=12),
        "ycrcb16sp": FeatureConfig(spatial_size=16),
        "ycrcb11_16": FeatureConfig(orientations=11, spatial_size=16),
        "yuv": FeatureConfig(color_space="YUV"),
        "hls": FeatureConfig(color_space="HLS"),
        "ycrcb12_16": FeatureConfig(orientations=12, spatial_size=16),
        "ycrcb12_h64": FeatureConfig(orientations=12, hist_bins=64),
        "ycrcb16": FeatureConfig(orientations=16),
        "ycrcb12_b3": FeatureConfig(orientations=12, cells_per_block=3),
        "luv12": FeatureConfig(color_space="LUV", orientations=12),
    }
    crops = load_crops(data_dir())
    print("| config | classifier | C | seed | sequence acc | P | R | random acc | P | R |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in args.configs.split(","):
        cfg = presets[name]
        t0 = time.perf_counter()
        x = features_in_chunks(crops.images, cfg, False)
        mirrored = np.ascontiguousarray(crops.images[:, :, ::-1])  # as `fastdet train` mirrors its crops
        xf = features_in_chunks(mirrored, cfg, False)
        for seed in [int(s) for s in args.seeds.split(",")]:
            splits = {"sequence": sequence_split(crops.groups, crops.order, seed),
                      "random": random_split(crops.labels, seed)}
            for clf_name, C in itertools.product(args.classifiers.split(","), [float(c) for c in args.C.split(",")]):
                row = []
                for sname in ("sequence", "random"):
                    tr, te = splits[sname]
                    xt = np.concatenate([x[tr], xf[tr]])
                    yt = np.concatenate([crops.labels[tr], crops.labels[tr]])
                    scaler, clf = fit_classifier(xt, yt, clf_name, C, seed)
                    m = metrics(crops.labels[te], clf.predict(scaler.transform(x[te])))
                    row += [f"{m['accuracy']:.4f}", f"{m['precision']:.4f}", f"{m['recall']:.4f}"]
                print(f"| {name} | {clf_name} | {C:g} | {seed} | " + " | ".join(row)
                      + f" |  ({time.perf_counter() - t0:.0f} s)",
                      flush=True)


if __name__ == "__main__":
    main()

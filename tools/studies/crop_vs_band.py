"""What HOG sub-sampling costs: band HOG (what the search sees) vs crop HOG (what training
sees) for the same windows (run by hand).

For every window of every default band of the six test images, compares the decision value
from the band's block map (``Detector.band_scores``, equal to the classic sub-sampling) with
``Model.decision_function`` of the window cut out as a 64x64 crop (its own HOG, gradients
zeroed on the crop border, as in training). Prints the spread of the difference and how
often the two disagree on the sign.
"""
from __future__ import annotations

import cv2
import numpy as np

from fastdet.data import data_dir
from fastdet.detect import Detector, scaled_band


def main() -> None:
    det = Detector()
    band_s, crop_s = [], []
    for p in sorted((data_dir() / "test_images").glob("*.jpg")):
        frame = cv2.imread(str(p))
        for geo in det.geometries(frame.shape[:2]):
            dense = det.band_scores(frame, geo)
            img = scaled_band(frame, geo)
            cell, win = det.config.pixels_per_cell, det.config.window
            crops = np.stack([img[i * geo.step * cell: i * geo.step * cell + win,
                                  j * geo.step * cell: j * geo.step * cell + win]
                              for i in range(geo.ny) for j in range(geo.nx)])
            band_s.append(dense.ravel())
            crop_s.append(det.model.decision_function(crops))
    b, c = np.concatenate(band_s), np.concatenate(crop_s)
    d = b - c
    print(f"{len(b)} windows: band - crop decision value: mean {d.mean():+.3f}, "
          f"median |diff| {np.median(np.abs(d)):.3f}, 95th percentile |diff| {np.percentile(np.abs(d), 95):.3f}")
    print(f"positive in the band: {int((b > 0).sum())}, as crops: {int((c > 0).sum())}, "
          f"sign disagrees on {int(((b > 0) != (c > 0)).sum())} windows "
          f"({100 * ((b > 0) != (c > 0)).mean():.2f}%)")


if __name__ == "__main__":
    main()

"""The bundled box regressor (``fastdet/models/refine.npz``): fit the learned box refinement
(:mod:`fastdet.video.refine`, fitted by :mod:`fastdet.train.refine`) on the annotated vehicles
of the clips ``--clips`` names and of the six test images (``tools/test_images.gt.txt``), and
write it to OUT.

    python -m tools.scripts.refine_model OUT.npz [--clips test_video] [--contexts 1.5]
        [--per-box 16] [--hog-channels 0] [--orientations 9] [--cell 8] [--spatial 8] [--seed 0]

The bundled regressor is fitted on ``test_video`` and the test images only, never on
``test_small1``, so that ``test_small1`` stays a held-out clip: ``python -m
tools.studies.refine_eval --clips test_small1 --ship fastdet/models/refine.npz`` measures
exactly this regressor held out and then writes it with that measurement in its metadata
(what the shipped file holds); this script writes the same regressor without it.
``--clips ''`` fits on the test images alone (a quick run).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fastdet.config import FeatureConfig
from fastdet.data import data_dir
from fastdet.detect.regressor import BoxFeatures, BoxRegressor
from fastdet.detections import Detections
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import FrameReader
from fastdet.train.refine import JitterConfig, Samples, collect_samples, fit_ridge

#: the annotated clips a regressor can be fitted on (``$FASTDET_DATA/videos``)
CLIPS = ("test_small1", "test_video")
TEST_IMAGES_GT = Path(__file__).resolve().parent.parent / "test_images.gt.txt"

Annotated = list[tuple[np.ndarray, np.ndarray, np.ndarray]]


def annotated(frames: list[np.ndarray], gt: Detections, group_base: int) -> Annotated:
    """``(frame, vehicle boxes (M, 4), groups (M,))`` of every frame with a ``consider = 1``
    box; a vehicle's group (``group_base`` + its id) keeps its samples in one CV fold."""
    out = []
    for f in np.unique(gt.frames[gt.consider]):
        sel = (gt.frames == f) & gt.consider
        if 1 <= f <= len(frames):
            out.append((frames[int(f) - 1], gt.boxes[sel], group_base + gt.ids[sel]))
    return out


def test_images() -> Annotated:
    """The six test images' annotated vehicles (ids unique over the six images)."""
    gt = read_gt(TEST_IMAGES_GT)
    imgs = [cv2.imread(str(data_dir() / "test_images" / f"test{i}.jpg")) for i in range(1, 7)]
    return annotated(imgs, gt, 900_000)


def clip_data(clip: str) -> tuple[list[np.ndarray], Detections]:
    """Every frame of ``$FASTDET_DATA/videos/CLIP.mp4`` (BGR) and its ground truth."""
    root = data_dir()
    reader = FrameReader(root / "videos" / f"{clip}.mp4")
    try:
        frames = [frame for _, frame, _ in reader]
    finally:
        reader.close()
    return frames, read_gt(root / "annotations" / f"{clip}.gt.txt")


def clip_vehicles(clip: str, data: tuple[list[np.ndarray], Detections] | None = None) -> Annotated:
    """:func:`annotated` of one of :data:`CLIPS` (``data``: its frames and ground truth, read
    when not given), groups numbered from ``1000 * (its place in CLIPS + 1)``."""
    frames, gt = data if data is not None else clip_data(clip)
    return annotated(frames, gt, 1000 * (CLIPS.index(clip) + 1))


def add_feature_arguments(ap: argparse.ArgumentParser) -> None:
    """The regressor's feature and sampling options (shared with ``tools.studies.refine_eval``)."""
    ap.add_argument("--contexts", default="1.5", help="context factors of the feature crops, comma-separated")
    ap.add_argument("--per-box", type=int, default=16, help="jittered samples per vehicle box (and as many mirrored)")
    ap.add_argument("--hog-channels", default="0", help="HOG channels of YCrCb, e.g. 0 or 0,1,2")
    ap.add_argument("--orientations", type=int, default=9)
    ap.add_argument("--cell", type=int, default=8, help="HOG pixels per cell")
    ap.add_argument("--spatial", type=int, default=8, help="spatial-bin side (0: none)")
    ap.add_argument("--seed", type=int, default=0)


def spec_of(a: argparse.Namespace) -> BoxFeatures:
    """The :class:`BoxFeatures` the options of :func:`add_feature_arguments` describe."""
    fcfg = FeatureConfig(color_space="YCrCb", hog_channels=tuple(int(c) for c in a.hog_channels.split(",")),
                         orientations=a.orientations, pixels_per_cell=a.cell, cells_per_block=2,
                         spatial_size=a.spatial, hist_bins=0)
    return BoxFeatures(fcfg, tuple(float(c) for c in a.contexts.split(",")))


def samples(vehicles: Annotated, spec: BoxFeatures, seed: int, per_box: int) -> Samples:
    """Training samples from ``vehicles`` plus the test images' vehicles."""
    return collect_samples(vehicles + test_images(), spec, seed=seed, jitter=JitterConfig(per_box=per_box))


def fit_box_regressor(smp: Samples, spec: BoxFeatures, metadata: dict[str, Any] | None = None) -> BoxRegressor:
    """:func:`fastdet.train.refine.fit_ridge` on ``smp`` (made with ``spec``), as a regressor
    whose metadata holds the fit's report (``"fit"``) and ``metadata``."""
    arrays, report = fit_ridge(smp, spec)
    return BoxRegressor.from_fit(spec, *arrays, metadata={**(metadata or {}), "fit": report})


def check_clips(names: list[str]) -> None:
    unknown = sorted(set(names) - set(CLIPS))
    if unknown:
        raise SystemExit(f"refine_model: error: unknown clip(s) {unknown}; choose from {list(CLIPS)}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="regressor file to write (.npz)")
    ap.add_argument("--clips", default="test_video",
                    help="clips to fit on besides the test images, comma-separated (default: test_video, so that "
                         "test_small1 stays held out; '' for the test images alone)")
    add_feature_arguments(ap)
    a = ap.parse_args(argv)
    clips = [c for c in a.clips.split(",") if c]
    check_clips(clips)
    spec = spec_of(a)
    vehicles = [v for c in clips for v in clip_vehicles(c)]
    reg = fit_box_regressor(samples(vehicles, spec, a.seed, a.per_box), spec, metadata={
        "trained_on": clips + ["test_images"],
        "command": "python -m tools.scripts.refine_model " + " ".join(argv if argv is not None else sys.argv[1:])})
    reg.save(a.out)
    fit = reg.metadata["fit"]
    print(f"wrote {a.out}: fitted on {'+'.join(clips + ['test_images'])}, {fit['samples']} samples of "
          f"{fit['groups']} vehicles, alpha {fit['alpha']:g}, CV mean IoU {max(fit['cv_mean_iou']):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

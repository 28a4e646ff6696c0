"""Study of the own-vehicle mask and of heat-blob splitting on the five annotated clips
(run by hand).

Runs the default video pipeline (``python -m fastdet eval --video`` builds the same one)
over every annotated clip with a variant's VideoDetector, scores the returned boxes at IoU
0.5 on the annotated frames only (the keyframes of a sparsely annotated clip: ``CLIP.frames``;
predictions elsewhere are neither hits nor false alarms) and prints one markdown row per
clip: P / R / F1 / false alarms per scored frame / CPU ms per frame (process time of the
whole run, horizon priming included). ``--save DIR`` keeps each run's boxes for a closer
look: ``VARIANT_CLIP.npz`` (plain arrays, read with ``allow_pickle=False``: :func:`load_run`)
beside ``VARIANT_CLIP.json`` (the variant's configuration, the scores, the CPU figure). A
``VARIANT_CLIP.pkl`` written by an earlier version of this study is not read (one line says so).

    python -m tools.studies.ownvehicle_study VARIANT [VARIANT ...] [--clips a,b] [--save /tmp/ov]
    python -m tools.studies.ownvehicle_study --split-load    # the split's most windows a frame
    python -m tools.studies.ownvehicle_study --split-noise /tmp/noise   # its worst frame on noise
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from fastdet.config import NeighbourSplit, OwnVehicleConfig, PipelineConfig
from fastdet.data import data_dir
from fastdet.detections import Detections
from fastdet.eval import evaluate
from fastdet.io.atomic import atomic_path
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import FrameReader
from fastdet.video.detector import make_detector
from fastdet.video.ownvehicle import OwnVehicleEstimator, OwnVehicleStage, window_fraction
from fastdet.video.pipeline import VideoDetector
from fastdet.video.run import video_detector_for
from tools.studies.frame_cache import pack_detections, unpack_detections

CLIPS = ("test_small1", "test_video", "highway_640", "boston_street", "motorcycle_highway")


#: where clips not in the data folder (synthetic variants) are looked for: CLIP.mp4, CLIP.gt.txt
EXTRA = Path(os.environ.get("OWNVEHICLE_EXTRA", "/tmp/ov/synth"))


def _video(clip: str) -> Path:
    if clip.endswith(".mp4") and Path(clip).is_file():  # a clip made here (split_noise)
        return Path(clip)
    p = data_dir() / "videos" / f"{clip}.mp4"
    return p if p.is_file() else EXTRA / f"{clip}.mp4"


def _annotation(clip: str, ext: str) -> Path:
    p = data_dir() / "annotations" / f"{clip}.{ext}"
    return p if p.is_file() or (data_dir() / "videos" / f"{clip}.mp4").is_file() else EXTRA / f"{clip}.{ext}"


def keyframes(clip: str) -> np.ndarray | None:
    p = _annotation(clip, "frames")
    if not p.is_file():
        return None
    return np.array([int(x) for x in p.read_text().split()], np.int64)


def score(clip: str, preds: Detections, iou: float = 0.5) -> dict[str, float]:
    """P / R / F1 / false alarms per scored frame of ``preds`` on ``clip``'s annotated frames
    (:func:`fastdet.eval.evaluate` with the clip's keyframes, as ``fastdet eval --all``)."""
    gt = read_gt(_annotation(clip, "gt.txt"))
    r = evaluate(gt, preds, iou=iou, keyframes=keyframes(clip), tracking=False)
    return {"P": r.precision, "R": r.recall, "F1": r.f1, "tp": r.tp, "fp": r.fp, "fn": r.fn,
            "fa": r.fp_per_frame, "frames": r.frames}


def run_clip(clip: str, config: PipelineConfig,
             keep: dict | None = None) -> tuple[Detections, list[dict], float]:
    """The boxes of every frame of ``clip`` with the pipeline of ``config`` (built as every
    command builds it: :func:`fastdet.video.run.video_detector_for`), per-frame debug (the heat
    maps' boxes, the windows, the heat and its labels) and the CPU seconds per frame of the
    whole run (priming counted, numba compilation not). ``keep``: given the
    :class:`~fastdet.video.pipeline.VideoDetector` run (``"detector"``)."""
    _warm()
    t0 = time.process_time()
    reader = FrameReader(_video(clip))
    debug: list[dict] = []
    out: list[tuple[int, Detections]] = []
    try:
        vd = video_detector_for(reader, make_detector(config), config)
        if keep is not None:
            keep["detector"] = vd
        for fno, frame, _ in reader:
            out.append((fno, vd.update(frame)))
            d = vd.debug
            debug.append({"frame": fno, "heat_boxes": d.boxes, "windows": d.windows,
                          "heat": d.heat.astype(np.float32), "labels": d.labels})
        own = vd.stage(OwnVehicleStage)
        if isinstance(own, OwnVehicleStage):
            region = own.region
            print(f"<!-- {clip}: own-vehicle region {0 if region is None else region.mean():.3f} of the frame, "
                  f"{own.dropped} windows dropped -->")
    finally:
        reader.close()
    cpu = (time.process_time() - t0) / max(len(out), 1)
    return Detections.from_frames(out, source=clip), debug, cpu



def save_run(out_dir: Path, variant: str, clip: str, preds: Detections, debug: list[dict],
             meta: dict) -> Path:
    """Write one run (:func:`run_clip`'s boxes and per-frame debug) to
    ``out_dir/VARIANT_CLIP.npz`` and ``meta`` (JSON-able: scores, configuration) with the
    variant, the clip and the frame count to ``VARIANT_CLIP.json``, each under a temporary
    name then renamed. The ``.npz`` holds plain arrays only: ``preds.*`` and the debug's
    ``heat_boxes.*`` / ``windows.*`` (:func:`~tools.studies.frame_cache.pack_detections`),
    ``frame`` ``(F,) int64``, ``grid`` ``(F, 2) int64`` (each frame's heat grid rows, columns)
    and ``heat`` (float32) / ``labels`` (int32), every frame's grid flattened in order.
    Returns the ``.npz`` path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    stem = out_dir / f"{variant}_{clip}"
    old = stem.with_suffix(".pkl")
    if old.is_file():
        print(f"ownvehicle_study: {old} is a pickle of an earlier version of this study and is not read "
              f"(this run writes {stem.name}.npz and .json)", file=sys.stderr)
    grids = [np.asarray(d["heat"]).shape for d in debug]
    arrays = {**pack_detections([preds], "preds."),
              **pack_detections([d["heat_boxes"] for d in debug], "heat_boxes."),
              **pack_detections([d["windows"] for d in debug], "windows."),
              "frame": np.array([d["frame"] for d in debug], np.int64),
              "grid": np.array(grids, np.int64).reshape(len(debug), 2),
              "heat": np.concatenate([np.asarray(d["heat"], np.float32).ravel() for d in debug] or
                                     [np.zeros(0, np.float32)]),
              "labels": np.concatenate([np.asarray(d["labels"], np.int32).ravel() for d in debug] or
                                       [np.zeros(0, np.int32)])}
    path = stem.with_suffix(".npz")
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    text = json.dumps({"variant": variant, "clip": clip, "frames": len(debug), **meta}, indent=1, default=float)
    with atomic_path(stem.with_suffix(".json")) as tmp:
        tmp.write_text(text + "\n")
    return path


def load_run(path: Path) -> tuple[Detections, list[dict]]:
    """The boxes and per-frame debug :func:`save_run` wrote to ``path`` (``.npz``, read with
    ``allow_pickle=False``): as :func:`run_clip` returned them (``preds`` without its source
    name)."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    preds = unpack_detections(arrays, "preds.")[0]
    heat_boxes = unpack_detections(arrays, "heat_boxes.")
    windows = unpack_detections(arrays, "windows.")
    debug, start = [], 0
    for i, (fno, (gh, gw)) in enumerate(zip(arrays["frame"].tolist(), arrays["grid"].tolist())):
        stop = start + gh * gw
        debug.append({"frame": fno, "heat_boxes": heat_boxes[i], "windows": windows[i],
                      "heat": arrays["heat"][start:stop].reshape(gh, gw),
                      "labels": arrays["labels"][start:stop].reshape(gh, gw)})
        start = stop
    return preds, debug

_WARM: list[bool] = []


def _warm() -> None:
    if not _WARM:
        VideoDetector(make_detector()).warmup()
        _WARM.append(True)


BASE = replace(PipelineConfig(), own_vehicle=None)  # the variants add the stage to a pipeline without it
VARIANTS: dict[str, PipelineConfig] = {
    "base": BASE,
    "own": replace(BASE, own_vehicle=OwnVehicleConfig()),
    "split": replace(BASE, split=NeighbourSplit()),
    "both": replace(BASE, own_vehicle=OwnVehicleConfig(), split=NeighbourSplit()),
}
for _a in (1.4, 1.6, 2.0, 2.5):
    VARIANTS[f"split_a{_a}"] = replace(BASE, split=NeighbourSplit(min_aspect=_a))
for _m in (0.25, 0.75):
    VARIANTS[f"split_w{_m}"] = replace(BASE, split=NeighbourSplit(min_weight=_m))
for _b in (0.15, 0.35):
    VARIANTS[f"split_b{_b}"] = replace(BASE, split=NeighbourSplit(bandwidth=_b))
for _s in (0.6, 0.9):
    VARIANTS[f"own_s{_s}"] = replace(BASE, own_vehicle=OwnVehicleConfig(min_still=_s))


def make_synthetic(out: Path) -> None:
    """A rigid dash on every frame: the motorcycle clip's first frame, rows 468-720 (its
    windscreen, dash and mirrors) scaled to the width, pasted over the bottom 35% of every
    frame of test_small1, test_video and highway_640 (``CLIP_dash35.mp4``, mp4v), with their
    ground truth (targets at least half under the dash become ignore regions) and keyframes."""
    out.mkdir(parents=True, exist_ok=True)
    r = FrameReader(data_dir() / "videos" / "motorcycle_highway.mp4", 0, 1, notify=lambda _n: None)
    dash = next(iter(r))[1][468:720]
    r.close()
    for clip in ("test_small1", "test_video", "highway_640"):
        r = FrameReader(data_dir() / "videos" / f"{clip}.mp4", notify=lambda _n: None)
        writer = None
        y0 = 0
        for _, f, _ in r:
            h, w = f.shape[:2]
            d = cv2.resize(dash, (w, round(dash.shape[0] * w / 1280)))
            y0 = h - d.shape[0]
            f = f.copy()
            f[y0:] = d
            if writer is None:
                writer = cv2.VideoWriter(str(out / f"{clip}_dash35.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), r.fps or 25,
                                         (w, h))
            writer.write(f)
        assert writer is not None
        writer.release()
        r.close()
        lines = []
        for line in (data_dir() / "annotations" / f"{clip}.gt.txt").read_text().splitlines():
            v = line.strip().split(",")
            top, hh = float(v[3]), float(v[5])
            if v[6] == "1" and top + hh - y0 > 0.5 * hh:
                v[6] = "0"
            lines.append(",".join(v))
        (out / f"{clip}_dash35.gt.txt").write_text("\n".join(lines) + "\n")
        kf = data_dir() / "annotations" / f"{clip}.frames"
        if kf.is_file():
            (out / f"{clip}_dash35.frames").write_text(kf.read_text())


def cost() -> None:
    """CPU of the own-vehicle estimator over the first 75 frames of test_small1 (1280x720) and
    of the window test per frame, and of split_boxes per frame on three clips."""
    from fastdet.video import blobsplit
    r = FrameReader(data_dir() / "videos" / "test_small1.mp4", 0, 75, notify=lambda _n: None)
    frames = [f for _, f, _ in r]
    r.close()
    best = math.inf
    for _ in range(3):
        est = OwnVehicleEstimator(fps=25)
        t = time.process_time()
        for f in frames:
            est.update(f)
        est.region()
        best = min(best, time.process_time() - t)
    print(f"own-vehicle estimator: {1000 * best / len(frames):.2f} ms a frame over the first {len(frames)} frames "
          f"of 1280x720 ({1000 * best:.0f} ms)")
    region = np.zeros((720, 1280), bool)
    region[600:] = True
    t = time.process_time()
    integral = cv2.integral(region.astype(np.uint8))
    t_int = time.process_time() - t
    boxes = np.array([[x, 400, x + 128, 528] for x in range(0, 1152, 16)])
    t = time.process_time()
    for _ in range(1000):
        window_fraction(region, boxes, integral)
    print(f"window test: {t_int * 1000:.2f} ms once per region, {(time.process_time() - t):.3f} ms a frame "
          f"({len(boxes)} windows)")
    tot = [0.0, 0]
    orig = blobsplit.split_boxes

    def timed(*a, **k):
        t0 = time.process_time()
        r = orig(*a, **k)
        tot[0] += time.process_time() - t0
        tot[1] += 1
        return r
    blobsplit.split_boxes = timed  # type: ignore[assignment]
    try:
        for clip in ("test_video", "test_small1", "highway_640"):
            tot[:] = [0.0, 0]
            run_clip(clip, VARIANTS["split"])
            print(f"split_boxes on {clip}: {1000 * tot[0] / max(tot[1], 1):.3f} ms a frame ({tot[1]} frames)")
    finally:
        blobsplit.split_boxes = orig  # type: ignore[assignment]


def split_load(clips: list[str]) -> None:
    """The neighbour split's load on each clip with today's defaults (``PipelineConfig()``):
    the most windows shifted in one frame and for one blob, and blobs its frame budget
    (``NeighbourSplit.max_frame_windows``) left whole."""
    from fastdet.video.blobsplit import SplitStage
    config = PipelineConfig()
    assert config.split is not None
    print(f"| clip | frames split looked at | most windows shifted a frame | most for one blob | "
          f"blobs left whole by the budget ({config.split.max_frame_windows}) |")
    print("|---|---:|---:|---:|---:|")
    for clip in clips:
        keep: dict = {}
        run_clip(clip, config, keep)
        stage = keep["detector"].stage(SplitStage)
        t = stage.tally
        print(f"| {clip} | {t.frames} | {t.most} | {t.blob_most} | {t.refused} |", flush=True)


#: the noisy clips of :func:`split_noise`: (width, height, patch width, patch height, gap, top row)
NOISE_CLIPS = ((1280, 720, 280, 80, 160, 400), (1920, 1080, 300, 100, 200, 600), (2560, 720, 280, 80, 160, 400))


def make_noise_clip(path: Path, w: int, h: int, pw: int, ph: int, gap: int, y0: int, n: int = 12,
                    seed: int = 0) -> Path:
    """``n`` frames of ``w x h`` (mp4v): grey, with patches ``pw x ph`` px of 8 px blocks of
    random colours at full contrast (new each frame), ``gap`` px apart, in rows from ``y0``:
    dense texture the detector fires on in thousands of windows, one wide heat blob per patch
    where the search reaches (a frame of many big blobs)."""
    rng = np.random.default_rng(seed)
    mask = np.zeros((h, w), bool)
    for y in range(y0, h, ph + gap):
        for x in range(0, w, pw + gap):
            mask[y:y + ph, x:x + pw] = True
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25, (w, h))
    try:
        for _ in range(n):
            blocks = rng.integers(0, 255, (h // 8 + 1, w // 8 + 1, 3), dtype=np.uint8)
            f = np.ascontiguousarray(np.repeat(np.repeat(blocks, 8, 0), 8, 1)[:h, :w])
            f[~mask] = 128
            writer.write(f)
    finally:
        writer.release()
    return path


def split_noise(out_dir: Path, repeats: int = 3) -> None:
    """The neighbour split's CPU time a frame on the noisy clips of :func:`make_noise_clip`
    (written to ``out_dir``) with today's defaults (``PipelineConfig()`` of the fastdet
    imported): per frame the least of ``repeats`` runs (process time of ``split_boxes``);
    prints the worst frame, the windows shifted there and the median frame. Uses no API the
    split had before its frame budget, so the same function measures an older checkout."""
    from fastdet.video import blobsplit
    out_dir.mkdir(parents=True, exist_ok=True)
    real_split, real_modes = blobsplit.split_boxes, blobsplit.window_modes
    shifted = [0]
    cpu: list[float] = []
    counts: list[int] = []

    def modes(w, t, *a, **k):
        shifted[0] += len(w)
        return real_modes(w, t, *a, **k)

    def split(*a, **k):
        shifted[0] = 0
        t0 = time.process_time()
        r = real_split(*a, **k)
        cpu.append(time.process_time() - t0)
        counts.append(shifted[0])
        return r

    print("| clip | frames | windows a frame (median) | worst frame: split CPU ms | windows shifted there | "
          "median frame: split CPU ms |")
    print("|---|---:|---:|---:|---:|---:|")
    blobsplit.split_boxes, blobsplit.window_modes = split, modes  # type: ignore[assignment]
    try:
        for spec in NOISE_CLIPS:
            path = make_noise_clip(out_dir / "noise_{}x{}.mp4".format(*spec[:2]), *spec)
            runs = []
            for _ in range(repeats):
                cpu.clear()
                counts.clear()
                keep: dict = {}
                run_clip(str(path), PipelineConfig(), keep)
                runs.append((list(cpu), list(counts)))
            best = np.min([c for c, _ in runs], axis=0)
            n_shift = runs[0][1]
            i = int(np.argmax(best))
            wins = keep["detector"].debug.windows
            print(f"| {path.name} | {len(best)} | {len(wins)} | {1000 * best[i]:.1f} | {n_shift[i]} | "
                  f"{1000 * np.median(best):.1f} |", flush=True)
    finally:
        blobsplit.split_boxes, blobsplit.window_modes = real_split, real_modes  # type: ignore[assignment]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("variants", nargs="*")
    ap.add_argument("--make-synthetic", metavar="DIR", help="write the rigid-dash copies of three clips to DIR")
    ap.add_argument("--cost", action="store_true", help="time the estimator, the window test and the split")
    ap.add_argument("--split-load", action="store_true",
                    help="the neighbour split's most windows a frame on each of --clips (today's defaults)")
    ap.add_argument("--split-noise", metavar="DIR",
                    help="write noisy clips of many big blobs to DIR and time the split's worst frame there")
    ap.add_argument("--clips", default=",".join(CLIPS))
    ap.add_argument("--save", default=None)
    a = ap.parse_args()
    if a.make_synthetic:
        make_synthetic(Path(a.make_synthetic))
    if a.cost:
        cost()
    if a.split_load:
        split_load(a.clips.split(","))
    if a.split_noise:
        split_noise(Path(a.split_noise))
    if not a.variants:
        return
    print("| variant | clip | P | R | F1 | TP | FP | FN | FA/frame | CPU ms/frame |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for v in a.variants:
        for clip in a.clips.split(","):
            preds, debug, cpu = run_clip(clip, VARIANTS[v])
            s = score(clip, preds)
            print(f"| {v} | {clip} | {s['P']:.3f} | {s['R']:.3f} | {s['F1']:.3f} | {s['tp']} | {s['fp']} | "
                  f"{s['fn']} | {s['fa']:.2f} | {1000 * cpu:.1f} |", flush=True)
            if a.save:
                save_run(Path(a.save), v, clip, preds, debug, {"scores": s, "cpu_ms_per_frame": 1000 * cpu,
                                                               "config": VARIANTS[v].to_dict()})

if __name__ == "__main__":
    main()

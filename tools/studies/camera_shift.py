"""Camera-shift suite: how the video pipeline fares on transformed copies of the annotated clips.

Every annotated clip of ``$FASTDET_DATA`` (``annotations/CLIP.gt.txt`` + ``videos/CLIP.mp4``)
is turned into each variant of :func:`fastdet.eval.variants.standard_variants` (other
resolutions, wider lenses, horizon moved, right border cutting cars, mirrored, re-encoded
with x264 CRF 23 and OpenCV's mp4v), its ground truth transformed with the pixels
(:func:`fastdet.eval.variants.transform_gt`: the annotation rules re-applied, cars narrower
than 40 reference px or less than half in view become ignore regions). The default video
pipeline (``VideoDetector``: main model + oncoming model behind the motion gate, default
heat maps and tracker, the horizon estimated from the clip's first frames as
``iter_video_detections`` does for a file) runs on each, and the tool prints F1 / precision /
recall / false positives per frame per variant per clip, and recall by box width in
reference (1280x720) pixels.

    python -m tools.studies.camera_shift [--variants original,960x540,...] [--clips test_small1]
        [--json OUT.json] [--cache DIR --tag NAME] [--heat split_gap=0.5 ...]
        [--horizon auto|reference|oracle] [--band S,Y0,Y1[,X0,X1]] [--border F] [--no-oncoming]
        [--model MAIN.npz] [--oncoming-model WIDE.npz]

``--cache DIR`` stores every frame's positive windows (per clip, variant and ``--tag``) and
replays them on the next run, so heat-map settings (``--heat``) can be compared without
running the detector again (a new ``--tag`` for every detector setting: ``--band``,
``--border``, ``--horizon``). Re-encoded copies are written under ``$TMPDIR``, never the repo.
"""
from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from fastdet.config import REFERENCE_HORIZON, HeatConfig, PipelineConfig, SearchBand
from fastdet.data import data_dir
from fastdet.detect import Detector
from fastdet.detections import ONCOMING_PART, Detections
from fastdet.eval import evaluate
from fastdet.eval.sizes import WIDTH_EDGES, recall_by_width
from fastdet.eval.variants import Variant, standard_variants, transform_gt
from fastdet.io.keyframes import keyframes_for
from fastdet.io.motfiles import read_gt
from fastdet.io.reader import read_frames
from fastdet.video import VideoDetector, make_detector
from tests.fakes import RecordingDetector
from tools.studies.frame_cache import load_frame_detections, save_frame_detections

# ---------------------------------------------------------------------------------------
# frames


#: variants this tool adds on request (``--variants``), with the OpenCV codec that re-encodes
#: them (:class:`Variant` itself knows only x264 and mp4v)
TOOL_CODECS = {"mjpg": "MJPG"}


def encode(frames: list[np.ndarray], codec: str, crf: int, out: Path, fps: float = 25.0) -> None:
    """Write ``frames`` (BGR) to ``out`` with x264 at ``crf`` (imageio-ffmpeg's binary) or
    OpenCV's mp4v or MJPG writer."""
    h, w = frames[0].shape[:2]
    if codec in ("mp4v", "MJPG"):
        wr = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*codec), fps, (w, h))
        if not wr.isOpened():
            raise SystemExit(f"OpenCV cannot write {codec}")
        for f in frames:
            wr.write(f)
        wr.release()
        return
    import imageio_ffmpeg

    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24",
           "-s", f"{w}x{h}", "-r", f"{fps:g}", "-i", "-", "-c:v", "libx264", "-crf", str(crf),
           "-pix_fmt", "yuv420p", str(out)]
    subprocess.run(cmd, input=b"".join(np.ascontiguousarray(f).tobytes() for f in frames), check=True)


def variant_frames(src: list[np.ndarray], variant: Variant, clip: str, tmp: Path) -> list[np.ndarray]:
    frames = [variant.frame(f) for f in src]
    codec = variant.codec or TOOL_CODECS.get(variant.name)
    if codec is None:
        return frames
    out = tmp / f"{clip}.{variant.name}.{'avi' if codec == 'MJPG' else 'mp4'}"
    encode(frames, codec, variant.crf, out)
    dec = read_frames(out)
    if len(dec) != len(frames):
        raise SystemExit(f"{out}: {len(dec)} frames decoded, {len(frames)} written")
    return dec


# ---------------------------------------------------------------------------------------
# the suite


def run_clip(det: Any, frames: list[np.ndarray], heat: HeatConfig, cache: Path | None,
             horizon: float | str | None) -> tuple[Detections, float]:
    """Boxes of every frame through a fresh VideoDetector (``horizon`` as its argument;
    ``'auto'`` primed with the clip's first frames, as ``iter_video_detections`` does for a
    file), and the seconds per frame."""
    replay = load_frame_detections(cache) if cache is not None and cache.exists() else None
    rec = RecordingDetector(det, replay)
    if horizon is None:
        det.set_horizon(None)
    vd = VideoDetector(rec, PipelineConfig(heat=heat, horizon=horizon))
    if horizon == "auto":
        vd.prime_horizon(frames)
    rec.warmup()
    t0 = time.perf_counter()
    out = [(i, vd.update(f)) for i, f in enumerate(frames, start=1)]
    dt = (time.perf_counter() - t0) / len(frames)
    if cache is not None and replay is None:
        save_frame_detections(cache, rec.record)
    return Detections.from_frames(out), dt


def iter_suite(variants: list[Variant], clips: list[str], det: Any, heat: HeatConfig, cache_dir: Path | None,
               tag: str, horizon: str = "auto") -> Iterator[dict[str, Any]]:
    root = data_dir()
    with tempfile.TemporaryDirectory(prefix="fastdet_camera_shift_") as tmpd:
        for clip in clips:
            src = read_frames(root / "videos" / f"{clip}.mp4")
            gt0 = read_gt(root / "annotations" / f"{clip}.gt.txt")
            kf = keyframes_for(root / "annotations" / f"{clip}.gt.txt")  # a keyframe clip: those frames only
            shape = src[0].shape[:2]
            for v in variants:
                frames = variant_frames(src, v, clip, Path(tmpd))
                gt = transform_gt(gt0, v, shape)
                hz: float | str | None = None if horizon == "reference" else "auto"
                if horizon == "oracle":  # the reference horizon moved with the pixels
                    row = REFERENCE_HORIZON * shape[0]
                    hz = float(v.boxes(np.array([[0, row, 1, row]]), shape)[0][0, 1]) / frames[0].shape[0]
                cache = cache_dir / f"{tag}.{clip}.{v.name}.npz" if cache_dir is not None else None
                preds, dt = run_clip(det, frames, heat, cache, hz)
                res = evaluate(gt, preds, iou=0.5, num_frames=None if kf is not None else len(frames), keyframes=kf)
                bins = recall_by_width(gt, preds, frames[0].shape[0], keyframes=kf,
                                       num_frames=None if kf is not None else len(frames))
                yield {"variant": v.name, "clip": clip, "shape": list(frames[0].shape[:2]), "frames": len(frames),
                       "horizon": det.horizon,
                       "scored_frames": res.frames, "targets": res.num_gt, "tp": res.tp, "fp": res.fp, "fn": res.fn,
                       "precision": res.precision, "recall": res.recall, "f1": res.f1,
                       "fp_per_frame": res.fp_per_frame, "ms_per_frame": 1000 * dt,
                       "width_bins": [[b.lo, b.hi, b.found, b.total] for b in bins]}


def pooled(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """One row summing the counts of ``rows`` (the clips of one variant)."""
    tp, fp, fn = (sum(r[k] for r in rows) for k in ("tp", "fp", "fn"))
    frames = sum(r["frames"] for r in rows)
    scored = sum(r["scored_frames"] for r in rows)  # the keyframes of a keyframe clip, else every frame
    bins = [[b[0], b[1], sum(r["width_bins"][i][2] for r in rows), sum(r["width_bins"][i][3] for r in rows)]
            for i, b in enumerate(rows[0]["width_bins"])]
    nan = float("nan")
    return {"variant": rows[0]["variant"], "clip": "all", "frames": frames, "scored_frames": scored,
            "targets": tp + fn, "tp": tp, "fp": fp,
            "fn": fn, "precision": tp / (tp + fp) if tp + fp else nan, "recall": tp / (tp + fn) if tp + fn else nan,
            "f1": 2 * tp / (2 * tp + fp + fn) if tp + fp + fn else nan, "fp_per_frame": fp / scored,
            "ms_per_frame": sum(r["ms_per_frame"] * r["frames"] for r in rows) / frames, "width_bins": bins}


def _bin_cell(b: list) -> str:
    return f"{b[2]}/{b[3]}" if b[3] else "-"


def format_rows(rows: list[dict[str, Any]]) -> str:
    labels = [f"{lo:g}+" if hi == float("inf") else f"{lo:g}-{hi:g}" for lo, hi in itertools.pairwise(WIDTH_EDGES)]
    head = ["variant", "clip", "targets", "P", "R", "F1", "FP/frame", *[f"R {x}" for x in labels], "ms/frame"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        f1 = f"{r['f1']:.3f}"
        if r["clip"] == "all":
            f1 = f"**{f1}**"
        lines.append("| " + " | ".join([r["variant"], r["clip"], str(r["targets"]), f"{r['precision']:.3f}",
                                        f"{r['recall']:.3f}", f1, f"{r['fp_per_frame']:.3f}",
                                        *[_bin_cell(b) for b in r["width_bins"]], f"{r['ms_per_frame']:.0f}"]) + " |")
    return "\n".join(lines)


def _heat_arg(s: str) -> tuple[str, Any]:
    k, _, v = s.partition("=")
    if not _ or k not in HeatConfig.__dataclass_fields__:
        raise argparse.ArgumentTypeError(f"expected FIELD=VALUE with a HeatConfig field, got {s!r}")
    return k, (v if k == "box_mode" else float(v))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", help="comma-separated variant names (default: all)")
    ap.add_argument("--clips", help="comma-separated clip names (default: every annotated clip)")
    ap.add_argument("--json", metavar="OUT.json", help="also write the rows as JSON")
    ap.add_argument("--cache", metavar="DIR", help="record / replay the detector windows here")
    ap.add_argument("--tag", default="default", help="name of the detector setting in the cache")
    ap.add_argument("--heat", type=_heat_arg, action="append", default=[], metavar="FIELD=VALUE",
                    help="override a HeatConfig field of the main heat map (repeatable)")
    ap.add_argument("--no-oncoming", action="store_true", help="main model only")
    ap.add_argument("--model", metavar="MAIN.npz", help="main model (default: the bundled one)")
    ap.add_argument("--oncoming-model", metavar="WIDE.npz", help="wide-window model for oncoming traffic "
                    "(default: the bundled one)")
    ap.add_argument("--band", action="append", default=[], metavar="SCALE,Y0,Y1[,X0,X1]",
                    help="add a band to the main search (1280x720 reference pixels; repeatable)")
    ap.add_argument("--wide-columns", metavar="X0,X1", help="columns (1280-wide reference pixels) of the "
                    "wide (oncoming) model's bands instead of 0..704, e.g. 0,1280 or 576,1280")
    ap.add_argument("--border", type=float, default=None, help="SearchConfig.border of the main search")
    ap.add_argument("--border-mode", choices=("reflect", "replicate"), default=None)
    ap.add_argument("--horizon", choices=("auto", "reference", "oracle"), default="auto",
                    help="search bands at the horizon the pipeline estimates from each clip (auto, the "
                         "default), at the reference horizon, or at the reference horizon moved with the "
                         "variant's pixels (oracle)")
    args = ap.parse_args(argv)

    variants = standard_variants()
    if args.variants:
        variants += [Variant(name) for name in TOOL_CODECS]
        want = args.variants.split(",")
        unknown = set(want) - {v.name for v in variants}
        if unknown:
            raise SystemExit(f"unknown variants {sorted(unknown)}; known: {[v.name for v in variants]}")
        variants = [v for v in variants if v.name in want]
    clips = (args.clips.split(",") if args.clips else
             sorted(p.name[: -len(".gt.txt")] for p in (data_dir() / "annotations").glob("*.gt.txt")))
    heat = replace(HeatConfig(), **dict(args.heat))
    if args.no_oncoming and args.oncoming_model:
        raise SystemExit("--no-oncoming and --oncoming-model exclude each other")
    det: Detector = make_detector(PipelineConfig(model=args.model,
                                                 oncoming=False if args.no_oncoming else (args.oncoming_model or True)))
    if args.band:
        extra = tuple(SearchBand(float(f[0]), *(int(v) for v in f[1:])) for f in (b.split(",") for b in args.band))
        sc = det.scorers[0]
        sc.search = replace(sc.search, bands=tuple(sc.search.bands) + extra)
    if args.wide_columns and ONCOMING_PART in det.parts:
        a, b = (int(v) for v in args.wide_columns.split(","))
        sc = det.scorers[det.parts.index(ONCOMING_PART)]
        sc.search = replace(sc.search, bands=tuple(
            replace(bd, x_start=a + int((b - a) % (8 * bd.scale)) if a else 0,
                    x_stop=b if a else int(b // (8 * bd.scale) * (8 * bd.scale))) for bd in sc.search.bands))
    if args.border is not None or args.border_mode is not None:
        sc = det.scorers[0]
        sc.search = replace(sc.search, border=sc.search.border if args.border is None else args.border,
                            border_mode=args.border_mode or sc.search.border_mode)
    cache = Path(args.cache) if args.cache else None
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

    rows: list[dict[str, Any]] = []
    by_variant: dict[str, list[dict[str, Any]]] = {}
    for r in iter_suite(variants, clips, det, heat, cache, args.tag, args.horizon):
        rows.append(r)
        by_variant.setdefault(r["variant"], []).append(r)
        print(f"{r['variant']:>14} {r['clip']:<12} F1 {r['f1']:.3f} P {r['precision']:.3f} R {r['recall']:.3f} "
              f"FP/frame {r['fp_per_frame']:.3f}", file=sys.stderr, flush=True)
    table = []
    for v in variants:
        rs = by_variant.get(v.name, [])
        table += rs + ([pooled(rs)] if len(rs) > 1 else [])
    print(format_rows(table))
    if args.json:
        Path(args.json).write_text(json.dumps({"heat": heat.to_dict(), "rows": table}, indent=1))
    det.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The box regressor fitted leave one camera out on every annotated clip (run by hand;
docs/geometry.md "The box regressor fitted on the other cameras" and "A regressor fitted on
the pipeline's own boxes").

For each annotated clip E of ``$FASTDET_DATA`` (the two Udacity clips and the keyframe clips),
a regressor (:mod:`fastdet.train.refine`, the features of :mod:`tools.scripts.refine_model`)
is fitted on the annotated vehicles (``consider = 1``) of the clips of every *other camera*
-- keyframes only for a keyframe clip; the two Udacity clips and the six test images are one
camera, so when E is one of them the other and the test images are left out too -- and E's
boxes are refined with it and scored: E is scored only by a regressor that never saw its
camera. Prints the per-clip table of ``fastdet eval --all`` (with HOTA where the clip is
annotated on every frame) and the box measurements of :mod:`tools.studies.small_boxes`.

The pipeline's boxes before the refinement do not depend on the regressor (the heat maps,
the tracker and the guided search keep the unrefined boxes), so every clip runs once with the
refinement and the plausibility rules (which run on the refined boxes) off, kept in
``--out-dir`` as ``unrefined_CLIP.npz``; each regressor refines those boxes on the scored
frames and the rules run on them as the pipeline's stage would (at the horizon the search
used on that frame): the same figures as the pipeline with that regressor.

Training inputs (``--inputs``):

- ``jitter`` (default): random boxes about each vehicle (:class:`~fastdet.config.JitterConfig`,
  ``--jitter-scale``, ``--jitter-aspect``, ``--per-box``), and their mirror images;
- ``own``: the pipeline's own boxes on the training clips' annotated frames (the returned
  boxes before refinement and the heat maps' boxes, ``--own-source``), each paired with the
  vehicle it overlaps most when that IoU is at least ``--own-iou``, and their mirror images,
  each ``--own-repeat`` times (a weight);
- ``both``: the two together.

``--cascade S`` fits S regressors, each on the (cross-validated) boxes the ones before it
made (:func:`fastdet.train.refine.fit_cascade`), into one file; refinement step ``i`` uses
the ``i``-th (``--refine iterations=N``; the last one for further steps).

    python -m tools.studies.refine_loo [--out-dir DIR [--reuse]] [--clips A,B] [--inputs jitter|own|both]
        [--own-iou 0.3] [--own-repeat K] [--own-source out|heat|both] [--cascade S]
        [--jitter-scale LO HI] [--jitter-aspect A]
        [small_boxes options, e.g. --refine iterations=3]

``--ship PATH --ship-without CLIP`` then fits one regressor on every clip but CLIP (default
``test_small1``, so that ``fastdet eval`` on it is not in-sample) and writes it to PATH with
the leave-one-camera-out figures of this run in its metadata (``leave_one_clip_out``). On the
other clips ``fastdet eval`` with that regressor is in-sample: their honest figures are this
study's.
"""
from __future__ import annotations

import argparse
import hashlib
import io
import json
import sys
import tempfile
import zipfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

import fastdet
from fastdet.config import JitterConfig, PipelineConfig
from fastdet.detect.regressor import BoxRegressor, load_regressor
from fastdet.detections import Detections
from fastdet.eval.clips import AnnotatedClip, annotated_clips, markdown_table, score_clip
from fastdet.io.atomic import write_bytes
from fastdet.io.reader import read_frames_at
from fastdet.train.refine import View, fit_cascade, jittered_views, matched_inputs, mirror
from fastdet.video.plausible import PlausibleStage
from fastdet.video.refine import refine
from tools.scripts.refine_model import Annotated, add_feature_arguments, spec_of, test_images

from .frame_cache import pack_detections, unpack_detections
from .small_boxes import add_setting_arguments, config_from, fa_summary, measure, print_tables, run_clip, summary

#: clips of one camera (anything learnt from one of them never scores another)
CAMERAS = {"test_small1": "udacity", "test_video": "udacity"}
#: the camera of the six test images (tools/test_images.gt.txt)
TEST_IMAGES_CAMERA = "udacity"


def camera_of(name: str) -> str:
    """The camera a clip was filmed with (its own name unless :data:`CAMERAS` says otherwise)."""
    return CAMERAS.get(name, name)


def training_clips(clips: list[str], held_out: str) -> tuple[list[str], bool]:
    """The clips a regressor scoring ``held_out`` may learn from (the other cameras'), and
    whether the test images may be among its training data."""
    cam = camera_of(held_out)
    return [c for c in clips if camera_of(c) != cam], TEST_IMAGES_CAMERA != cam


@dataclass
class ClipRun:
    """One clip's pipeline run without refinement: ``frames [(fno, Detections)]``, the records
    of the scored frames (:func:`tools.studies.small_boxes.run_clip`), its height ``rows`` and
    the scored frames' pictures ``images {fno: (H, W, 3) uint8 BGR}``."""

    clip: AnnotatedClip
    frames: list
    rec: dict
    rows: int
    images: dict[int, np.ndarray]


def _code_digest() -> str:
    """SHA-256 of fastdet's source files and bundled models: a cached run is redone when the
    pipeline's code or models change, not only its configuration."""
    root = Path(fastdet.__file__).resolve().parent
    h = hashlib.sha256()
    for f in sorted([*root.rglob("*.py"), *(root / "models").glob("*.npz")]):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


#: the format of the unrefined runs' cache files (:func:`save_run`)
RUN_FORMAT = "refine_loo.unrefined/1"


def save_run(path: Path, key: str, frames: list, rec: dict, rows: int) -> None:
    """Write one clip's unrefined run to ``path`` (``.npz`` of plain arrays; no pickle):
    the boxes of every frame and, per scored frame, the returned boxes, the heat maps' boxes,
    the main model's windows (:func:`~tools.studies.frame_cache.pack_detections` under
    ``frames.``, ``out.``, ``boxes.``, ``windows.``), the heat map (``heat.I``, the I-th scored
    frame) and in ``metadata`` (UTF-8 JSON, ``uint8``) the format, ``key``, ``rows``, the scored
    frames and the horizon each used."""
    fnos = sorted(rec)
    arrays: dict[str, np.ndarray] = {"frames.fno": np.array([f for f, _ in frames], np.int64)}
    arrays.update(pack_detections([d for _, d in frames], "frames."))
    for name in ("out", "boxes", "windows"):
        arrays.update(pack_detections([rec[f][name] for f in fnos], name + "."))
    for i, f in enumerate(fnos):
        arrays[f"heat.{i}"] = np.asarray(rec[f]["heat"])
    extra = sorted({k for f in fnos for k in rec[f]} - {"out", "boxes", "windows", "heat", "horizon"})
    if extra:
        raise ValueError(f"save_run: records with {extra} are not stored")
    meta = {"format": RUN_FORMAT, "key": key, "rows": int(rows), "scored": fnos,
            "horizons": [None if rec[f]["horizon"] is None else float(rec[f]["horizon"]) for f in fnos]}
    arrays["metadata"] = np.frombuffer(json.dumps(meta).encode("utf-8"), np.uint8)
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes(path, buf.getvalue())


def load_run(path: Path) -> tuple[str, list, dict, int] | None:
    """``(key, frames, rec, rows)`` of a file :func:`save_run` wrote, or ``None`` (with a
    line on stderr) when it is of another format or cannot be read."""
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(arrays["metadata"].tobytes().decode("utf-8"))
        if meta.get("format") != RUN_FORMAT:
            raise ValueError(f"format {meta.get('format')!r}, not {RUN_FORMAT!r}")
        frames = list(zip(arrays["frames.fno"].tolist(), unpack_detections(arrays, "frames.")))
        parts = {name: unpack_detections(arrays, name + ".") for name in ("out", "boxes", "windows")}
        rec = {f: {"out": parts["out"][i], "boxes": parts["boxes"][i], "windows": parts["windows"][i],
                   "heat": arrays[f"heat.{i}"], "horizon": meta["horizons"][i]}
               for i, f in enumerate(meta["scored"])}
        return meta["key"], frames, rec, int(meta["rows"])
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile) as exc:
        print(f"refine_loo: {path}: not a run cache this study can read ({exc}); running the clip again",
              file=sys.stderr)
        return None


def unrefined_run(clip: AnnotatedClip, a: argparse.Namespace, out_dir: Path) -> ClipRun:
    """The pipeline of the options (``config_from``) with the refinement and the plausibility
    rules off, over ``clip``; kept in ``out_dir`` (``unrefined_CLIP.npz``, :func:`save_run`)
    and read from there when the configuration is the same (and fastdet's code and models,
    :func:`_code_digest`). A cache of an earlier version of this study (``unrefined_CLIP.pkl``,
    a pickle) is not read: the clip runs again."""
    config = replace(config_from(a), refine=None, plausible=None)
    key = hashlib.sha256(json.dumps([config.to_dict(), str(clip.video), _code_digest()], sort_keys=True,
                                    default=str).encode()).hexdigest()[:16]
    path = out_dir / f"unrefined_{clip.name}.npz"
    old = path.with_suffix(".pkl")
    if old.is_file() and not path.is_file():
        print(f"refine_loo: {old} is a pickle of an earlier version of this study and is not read; "
              f"running {clip.name} again (into {path.name})", file=sys.stderr)
    got = load_run(path) if path.is_file() else None
    if got is not None and got[0] == key:
        _, frames, rec, rows = got
    else:
        frames, rec, rows, _ = run_clip(clip, config)
        save_run(path, key, frames, rec, rows)
    images = read_frames_at(clip.video, sorted(rec), notify=lambda _n: None)
    return ClipRun(clip, frames, rec, rows, images)


def annotated_frames(run: ClipRun, index: int) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """``(frame number, frame, vehicle boxes (M, 4), groups (M,))`` of every scored frame of
    ``run`` with a ``consider = 1`` box (keyframes only, for a keyframe clip); groups from
    ``1000 * (index + 1)`` plus the vehicle's id, so one vehicle's samples stay in one CV fold."""
    gt = run.clip.gt()
    assert gt.ids is not None and gt.frames is not None and gt.consider is not None  # ground truth has them
    out = []
    for fno in sorted(run.rec):
        sel = (gt.frames == fno) & gt.consider
        if sel.any():
            out.append((fno, run.images[fno], gt.boxes[sel].astype(np.float64), 1000 * (index + 1) + gt.ids[sel]))
    return out


def clip_vehicles(run: ClipRun, index: int) -> Annotated:
    """:func:`annotated_frames` without the frame numbers."""
    return [(frame, boxes, groups) for _, frame, boxes, groups in annotated_frames(run, index)]


def own_views(run: ClipRun, index: int, min_iou: float, source: str) -> list[View]:
    """The pipeline's own boxes (before refinement) on ``run``'s annotated frames, each with
    the vehicle it overlaps most at IoU >= ``min_iou`` (:func:`fastdet.train.refine.matched_inputs`);
    ``source``: ``out`` (the returned boxes), ``heat`` (the heat maps' boxes) or ``both``."""
    views = []
    for fno, frame, targets, groups in annotated_frames(run, index):
        r = run.rec[fno]
        boxes = [d.boxes.reshape(-1, 4) for name, d in (("out", r["out"]), ("heat", r["boxes"]))
                 if source in (name, "both")]
        b, t, g = matched_inputs(np.concatenate(boxes).astype(np.float64), targets, groups, min_iou)
        if len(b):
            views.append(View(frame, b, t, g))
    return views


def training_views(runs: dict[str, ClipRun], names: list[str], images: bool, a: argparse.Namespace) -> list[View]:
    """The views a regressor is fitted on: the clips ``names`` (and the test images when
    ``images``), as ``--inputs`` says."""
    order = list(runs)
    views: list[View] = []
    if a.inputs in ("jitter", "both"):
        frames = [v for n in names for v in clip_vehicles(runs[n], order.index(n))]
        jitter = JitterConfig(per_box=a.per_box, scale=(a.jitter_scale[0], a.jitter_scale[1]),
                              aspect=a.jitter_aspect)
        views += jittered_views(frames + (test_images() if images else []), seed=a.seed, jitter=jitter)
    if a.inputs in ("own", "both"):
        own = [v for n in names for v in own_views(runs[n], order.index(n), a.own_iou, a.own_source)]
        views += [w for v in own for w in (v, mirror(v))] * a.own_repeat
    return views


def fit_without(runs: dict[str, ClipRun], held_out: str, a: argparse.Namespace, path: Path,
                metadata: dict[str, Any] | None = None, loo: bool = True) -> BoxRegressor:
    """Fit the regressor (a cascade of ``--cascade`` stages) on the clips of every camera but
    ``held_out``'s (``loo``; otherwise on every clip but ``held_out``) and save it to ``path``."""
    spec = spec_of(a)
    if loo:
        names, images = training_clips(list(runs), held_out)
    else:
        names, images = [n for n in runs if n != held_out], True
    views = training_views(runs, names, images, a)
    fits = fit_cascade(views, spec, a.cascade)
    stages = [BoxRegressor.from_fit(spec, *arrays) for arrays, _ in fits]
    reports = [report for _, report in fits]
    reg = BoxRegressor.stack(stages, metadata={
        "trained_on": names + (["test_images"] if images else []), "held_out_clip": held_out,
        "inputs": a.inputs, "own_iou": a.own_iou,
        "own_repeat": a.own_repeat,
        "own_source": a.own_source,
        "command": "python -m tools.studies.refine_loo " + " ".join(sys.argv[1:]), **(metadata or {}),
        "fit": reports[0], "stage_fits": reports})
    reg.save(path)
    for i, report in enumerate(reports):
        print(f"{path}: stage {i + 1}, without {held_out}: {report['samples']} samples of {report['groups']} "
              f"vehicles, alpha {report['alpha']:g}, CV mean IoU {max(report['cv_mean_iou']):.3f}, "
              f"training IoU {report['input_mean_iou']:.3f} -> {report['output_mean_iou']:.3f} (cross-validated)",
              flush=True)
    return reg


def refined(run: ClipRun, reg: BoxRegressor, config: PipelineConfig) -> tuple[list, dict]:
    """``run``'s frames and records with the scored frames' boxes refined by ``reg`` (when
    ``config.refine`` is on) and then filtered by ``config.plausible`` (when on), as the
    pipeline's stages would."""
    rec = {f: dict(r) for f, r in run.rec.items()}
    for f, r in rec.items():
        out = r["out"]
        if config.refine is not None:
            out = refine(run.images[f], out, reg, config.refine)
        if config.plausible is not None:
            out = PlausibleStage(config.plausible).filter(out)
        r["out"] = out
    frames = [(f, rec[f]["out"] if f in rec else out) for f, out in run.frames]
    return frames, rec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", default=None, help="where the regressors go (default: a temporary folder)")
    ap.add_argument("--clips", default=None, help="held-out clips to score (default: every annotated clip)")
    ap.add_argument("--ship", default=None,
                    help="after the measurement, fit on every clip but --ship-without and write it here, with the "
                         "leave-one-clip-out figures in its metadata")
    ap.add_argument("--ship-without", default="test_small1")
    ap.add_argument("--reuse", action="store_true",
                    help="use the regressors already in --out-dir (refine_without_CLIP.npz, same options)")
    ap.add_argument("--jitter-scale", type=float, nargs=2, default=JitterConfig().scale, metavar=("LO", "HI"),
                    help="size factors of the training boxes about each vehicle (default: JitterConfig's)")
    ap.add_argument("--jitter-aspect", type=float, default=JitterConfig().aspect,
                    help="largest |log| aspect change of the training boxes (default: JitterConfig's)")
    ap.add_argument("--inputs", choices=("jitter", "own", "both"), default="jitter",
                    help="training boxes: jittered about the vehicles, the pipeline's own, or both")
    ap.add_argument("--own-iou", type=float, default=0.3, help="smallest IoU of an own box with its vehicle")
    ap.add_argument("--own-repeat", type=int, default=1, help="times each own box counts")
    ap.add_argument("--own-source", choices=("out", "heat", "both"), default="both",
                    help="own boxes: the returned ones before refinement, the heat maps', or both")
    ap.add_argument("--cascade", type=int, default=1, help="regressors in the cascade (1: one, applied every step)")
    add_feature_arguments(ap)
    add_setting_arguments(ap)
    a = ap.parse_args()
    if a.cascade < 1 or a.own_repeat < 1 or not 0 <= a.own_iou <= 1:
        ap.error("--cascade and --own-repeat must be >= 1, --own-iou in 0..1")
    out_dir = Path(a.out_dir or tempfile.mkdtemp(prefix="refine_loo_"))
    out_dir.mkdir(parents=True, exist_ok=True)
    clips = annotated_clips()
    runs = {c.name: unrefined_run(c, a, out_dir) for c in clips}
    refine_cfg = config_from(a).refine
    held = [c for c in clips if a.clips is None or c.name in a.clips.split(",")]
    scores, tables, fa_lines, hotas = [], [], [], []
    fitted: dict[str, BoxRegressor] = {}  # one fit per held-out camera, a file per clip
    for clip in held:
        cam = camera_of(clip.name)
        path = out_dir / f"refine_without_{clip.name}.npz"
        if cam in fitted:
            reg = fitted[cam]
            if not (a.reuse and path.is_file()):
                reg.save(path)
        elif a.reuse and path.is_file():
            reg = load_regressor(path)
            if reg.n_stages != a.cascade:
                raise SystemExit(f"refine_loo: {path} has {reg.n_stages} stages, not --cascade {a.cascade}")
            if reg.spec != spec_of(a):
                raise SystemExit(f"refine_loo: {path} takes other features than the options give; "
                                 "fit again without --reuse")
        else:
            reg = fit_without(runs, clip.name, a, path)
        fitted[cam] = reg
        run = runs[clip.name]
        frames, rec = refined(run, reg, config_from(a))
        preds = Detections.from_frames(frames, source=str(clip.video))
        score = score_clip(clip.name, clip.gt(), preds, run.rows, clip.keyframes())
        scores.append(score)
        if score.result.hota is not None and clip.keyframes() is None:
            hotas.append(f"{clip.name}: HOTA {score.result.hota:.3f} (DetA {score.result.deta:.3f}, "
                         f"AssA {score.result.assa:.3f}), IDF1 {score.result.idf1:.3f}")
        m = measure(clip, rec, run.rows, int(config_from(a).heat.cell))
        tables += summary(clip.name, m)
        fa_lines.append(fa_summary(clip.name, m, len(rec)))
    print(markdown_table(scores))
    print("\n".join(hotas))
    print_tables(tables, fa_lines)
    if a.ship:
        keys = ("precision", "recall", "f1", "ap", "fp_per_frame", "tp", "fp")
        loo = {s.name: {k: s.result.to_dict()[k] for k in keys} for s in scores}
        fit_without(runs, a.ship_without, a, Path(a.ship),
                    {"leave_one_clip_out": loo, "refine_config": None if refine_cfg is None else refine_cfg.to_dict()},
                    loo=False)


if __name__ == "__main__":
    main()

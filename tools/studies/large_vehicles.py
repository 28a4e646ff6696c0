"""Large and near vehicles (at least 120 px wide in 1280-wide pixels) on every annotated clip
(run by hand; docs/geometry.md, "Large and near vehicles").

``--windows``: on the annotated frames (the keyframes of a keyframe clip, every 5th frame of
the others: the hand-read ones) each large target is compared with

* today's search (the main model's bands where the pipeline puts them: the flow horizon, or
  the reference one when the flow gives none): the best IoU any of its windows can have with
  the target (geometry alone, scores not looked at);
* a search at every size, each scale over the whole frame height (``--scales``, windows two
  cells apart as the default search, the main model): per target the best decision value of a window at IoU >= 0.5
  (``match``) and at IoU >= 0.3 (``near``), and how many *false* windows of the same scale
  there are per frame at that value or above (a false window: IoU < 0.3 with every target
  and less than half of it on ignore regions), on this clip.

``--pipeline``: runs the video pipeline (the code behind ``fastdet video``) with the main
search's bands given by ``--bands`` (default: today's) and says for every large target where
it is lost: no positive main window at IoU >= 0.5 (``detector``), a window but no heat-map box
at IoU >= 0.5 (``heat map``), a heat-map box but no output box (``tracker``); then the
``fastdet eval --all`` table of the run. (Its ``--large`` and ``--side`` runs, the large search or
the side-view component as a component with a heat map of its own, went with the side-view
component: docs/accuracy.md, "Deleted stages".)

    python -m tools.studies.large_vehicles --windows [--clips A,B] [--scales 3,3.75,...] [--model M.npz]
    NUMBA_NUM_THREADS=1 python -m tools.studies.large_vehicles --cost
    python -m tools.studies.large_vehicles --pipeline [--bands 4:300:720,...] [--clips A,B] [--verbose]
"""
from __future__ import annotations

import argparse
from collections import defaultdict
from dataclasses import replace

import numpy as np

from fastdet.boxes import iou, overlap_fraction
from fastdet.config import PipelineConfig, SearchBand, SearchConfig
from fastdet.config.search import LARGE_SEARCH
from fastdet.detect.bands import window_boxes
from fastdet.detect.detector import Detector, DetectStats
from fastdet.detections import MAIN_PART, Detections
from fastdet.eval.clips import AnnotatedClip, annotated_clips, markdown_table, score_clip
from fastdet.io.reader import FrameReader, read_frames, read_frames_at
from fastdet.video import make_detector
from fastdet.video.horizon import HORIZON_FRAMES, estimate_horizon
from fastdet.video.run import video_detector_for
from tools.studies.band_cost import detect_cpu_ms, parse_bands

#: width (reference pixels, 720-row frame) from which a target counts as large
LARGE = 120.0
#: scales of the every-size search (x 64 px at 1280x720): today's largest, 3, and up to 640 px
STUDY_SCALES = (2.0, 2.5, 3.0, 3.75, 4.5, 5.5, 7.0, 8.5, 10.0)


#: decision values at which the false windows per frame are counted
FA_LEVELS = (0, 2, 4, 6, 8)


def scored_frames(clip: AnnotatedClip) -> np.ndarray:
    """The hand-read frames: the keyframes, or every 5th frame from 1."""
    kf = clip.keyframes()
    if kf is not None:
        return np.asarray(kf, np.int64)
    gt = clip.gt()
    return np.arange(1, int(gt.frames.max()) + 1, 5)


def flow_horizon(clip: AnnotatedClip) -> float | None:
    return estimate_horizon(iter(read_frames(clip.video, frames=HORIZON_FRAMES)))


def all_windows(geo, config) -> np.ndarray:
    """Boxes of every window position of a band, row-major ``(ny * nx, 4)``."""
    r, c = np.divmod(np.arange(geo.ny * geo.nx), max(geo.nx, 1))
    return window_boxes(geo, r, c, config)


def frame_truth(gt, fno: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Targets, their ids and the ignore boxes of frame ``fno``."""
    m = gt.frames == fno
    return gt.boxes[m & gt.consider], gt.ids[m & gt.consider], gt.boxes[m & ~gt.consider]


def windows_study(clips: list[AnnotatedClip], scales: tuple[float, ...],
                  bands: tuple[SearchBand, ...] | None = None, model: str | None = None) -> None:
    today = SearchConfig()
    whole = bands is None
    study = replace(today, bands=bands if bands is not None else tuple(SearchBand(s, 0, 720) for s in scales))
    print("| clip | frame | id | w x h (ref px) | bottom (ref px) | today: best IoU (scale) | "
          "main: match dec (scale) | FA/frame >= it | near dec (scale) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for clip in clips:
        gt = clip.gt()
        frames_wanted = scored_frames(clip)
        frames = read_frames_at(clip.video, frames_wanted)
        shape = next(iter(frames.values())).shape[:2]
        hz = flow_horizon(clip)
        todays = replace(today, horizon=hz).for_frame(shape)
        # the whole-height bands stay where they are; bands given follow the horizon as the pipeline's do
        search = study if whole else replace(study, horizon=hz)
        det = Detector(model, search=search)
        tgeos = [band_geo for band_geo in Detector(search=todays).geometries(shape)]
        tboxes = [(g.band.scale, all_windows(g, det.config)) for g in tgeos]
        f = 720.0 / shape[0]
        rows = []
        # false windows per scale: their decision values over all frames
        false_dec: dict[tuple[int, float], list[np.ndarray]] = defaultdict(list)
        for fno in sorted(frames):
            targets, ids, ignore = frame_truth(gt, fno)
            stats = DetectStats()
            det.detect(frames[fno], stats=stats)
            per_band = []
            for part, geo, dec in stats.bands:
                boxes = all_windows(geo, det.config)
                d = dec.reshape(-1)
                ious = iou(boxes, targets) if len(targets) else np.zeros((len(boxes), 0))
                on_ign = np.zeros(len(boxes), bool)
                if len(ignore):
                    on_ign = overlap_fraction(boxes, ignore).max(axis=1) >= 0.5
                false = (ious.max(axis=1, initial=0.0) < 0.3) & ~on_ign
                false_dec[(part, round(geo.band.scale * f, 2))].append(d[false])
                per_band.append((part, round(geo.band.scale * f, 2), ious, d))
            for k, (t, tid) in enumerate(zip(targets, ids)):
                w, h = (t[2] - t[0]) * f, (t[3] - t[1]) * f
                if w < LARGE:
                    continue
                best_t = max(((float(iou(b, t[None]).max(initial=0.0)), s * f) for s, b in tboxes), default=(0.0, 0.0))

                def best(part: int, thr: float):
                    cand = [(float(d[ious[:, k] >= thr].max()), s) for p, s, ious, d in per_band
                            if p == part and (ious[:, k] >= thr).any()]
                    return max(cand) if cand else None

                rows.append((fno, int(tid), w, h, t[3] * f, best_t, best(MAIN_PART, 0.5), best(MAIN_PART, 0.3)))
        n = len(frames)

        def fa_rate(part: int, hit) -> str:
            if hit is None:
                return "-"
            d = np.concatenate(false_dec[(part, hit[1])]) if false_dec[(part, hit[1])] else np.zeros(0)
            return f"{(d >= hit[0]).sum() / n:.1f}"

        def fmt(hit) -> str:
            return "-" if hit is None else f"{hit[0]:+.2f} ({hit[1]:g})"

        for fno, tid, w, h, bottom, bt, m, near in rows:
            cells = [clip.name, str(fno), str(tid), f"{w:.0f} x {h:.0f}", f"{bottom:.0f}",
                     f"{bt[0]:.3f} ({bt[1]:g})", fmt(m), fa_rate(MAIN_PART, m), fmt(near)]
            print("| " + " | ".join(cells) + " |")
        # false windows per frame above decision values 0 .. 8, per scale
        per = []
        for (_, s), ds in sorted(false_dec.items()):
            d = np.concatenate(ds)
            per.append(f"{s:g}: " + "/".join(f"{(d > t).sum() / n:.1f}" for t in FA_LEVELS))
        print(f"<!-- {clip.name} main: false windows / frame above {'/'.join(map(str, FA_LEVELS))}, "
              f"by scale: {', '.join(per)}; horizon {hz if hz is None else round(hz, 3)} -->")


def pipeline_study(clips: list[AnnotatedClip], bands: tuple[SearchBand, ...] | None,
                   verbose: bool = False, horizon: float | str | None = "auto") -> None:
    config = PipelineConfig(horizon=horizon)
    if bands is not None:
        config = replace(config, search=replace(config.search, bands=bands))
    scores = []
    losses: dict[str, dict[str, int]] = {}
    for clip in clips:
        gt = clip.gt()
        wanted = set(int(x) for x in scored_frames(clip))
        kf = clip.keyframes()
        r = FrameReader(clip.video)
        done: list = []
        counts = {"targets": 0, "detector": 0, "heat map": 0, "tracker": 0, "found": 0}
        fates: list[str] = []
        try:
            vd = video_detector_for(r, make_detector(config), config)
            shape = r.shape[:2]
            fr = 720.0 / shape[0]
            for fno, frame, _ in r:
                out = vd.update(frame)
                done.append((fno, out))
                if fno not in wanted:
                    continue
                targets, ids, _ = frame_truth(gt, fno)
                w = vd.debug.windows
                main = w[w.part == MAIN_PART] if w.part is not None else w
                for t, tid in zip(targets, ids):
                    if (t[2] - t[0]) * fr < LARGE:
                        continue
                    counts["targets"] += 1
                    if len(out) and iou(out.boxes, t[None]).max() >= 0.5:
                        fate = "found"
                    elif len(vd.debug.boxes) and iou(vd.debug.boxes.boxes, t[None]).max() >= 0.5:
                        fate = "tracker"
                    elif len(main) and iou(main.boxes, t[None]).max() >= 0.5:
                        fate = "heat map"
                    else:
                        fate = "detector"
                    counts[fate] += 1
                    fates.append(f"{fno}:{tid}:{fate if fate != 'heat map' else 'heat'}")
        finally:
            r.close()
        preds = Detections.from_frames(done, source=str(clip.video))
        scores.append(score_clip(clip.name, gt, preds, shape[0], kf))
        losses[clip.name] = counts
        if verbose:
            print(f"{clip.name}: large targets (frame:id:fate) {' '.join(fates)}")
    print(markdown_table(scores))
    print()
    print("| clip | large targets | found | lost at: detector | heat map | tracker |")
    print("|---|---|---|---|---|---|")
    for name, c in losses.items():
        print(f"| {name} | {c['targets']} | {c['found']} | {c['detector']} | {c['heat map']} | {c['tracker']} |")


def cost_study(clip: str = "test_small1", frames: int = 20, repeat: int = 5) -> None:
    """HOG cells and windows per 1280x720 frame of the main search, the oncoming search and the
    large search, and the CPU of ``Detector.detect`` (full search, the video pipeline's
    detector) and of the large search alone (the main model on :data:`LARGE_SEARCH`), alternating,
    median of ``repeat`` passes over ``frames`` frames (``time.process_time``: all threads); "with
    the large search" is their sum."""
    shape = (720, 1280)
    today = make_detector(PipelineConfig())
    large = Detector(search=LARGE_SEARCH)

    def count(det: Detector) -> tuple[int, int]:
        cells = windows = 0
        for part in det.parts:
            for g in det.geometries(shape, part):
                cells += (g.scaled_w // 8) * (g.scaled_h // 8)
                windows += g.n_windows
        return cells, windows

    (c0, w0), (cl, wl) = count(today), count(large)
    c1, w1 = c0 + cl, w0 + wl
    print(f"HOG cells / windows per 1280x720 frame (full search, every model): today {c0} / {w0}, "
          f"with the large search {c1} / {w1}: {c1 / c0:.3f}x / {w1 / w0:.3f}x")
    a, alone = detect_cpu_ms([today, large], read_frames(annotated_clip(clip).video, frames=frames), repeat)
    b = a + alone
    print(f"Detector.detect CPU: today {a:.1f} ms/frame, with the large search {b:.1f}: {b / a:.2f}x "
          f"({frames} frames of {clip}, median of {repeat}; NUMBA_NUM_THREADS as set)")


def annotated_clip(name: str) -> AnnotatedClip:
    for c in annotated_clips():
        if c.name == name:
            return c
    raise SystemExit(f"no annotated clip {name!r}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--windows", action="store_true")
    ap.add_argument("--pipeline", action="store_true")
    ap.add_argument("--cost", action="store_true", help="cells, windows and CPU of the large search (cost_study)")
    ap.add_argument("--horizon", default="auto", help="--pipeline: auto, off or a fraction of the height")
    ap.add_argument("--verbose", action="store_true", help="--pipeline: every large target's fate")
    ap.add_argument("--clips", default=None)
    ap.add_argument("--model", default=None, help="--windows: main model file (default: the bundled one), "
                    "e.g. a camera's from fastdet adapt")
    ap.add_argument("--scales", default=None, help="--windows: scales (x 64 px at 1280x720)")
    ap.add_argument("--bands", default=None, help="main bands scale:y0:y1[:x0:x1],... (1280x720 px; "
                    "--pipeline: instead of today's, --windows: instead of the whole-height ones of --scales)")
    args = ap.parse_args()
    clips = annotated_clips()
    if args.clips:
        want = args.clips.split(",")
        clips = [c for c in clips if c.name in want]
    if args.windows:
        scales = tuple(float(s) for s in args.scales.split(",")) if args.scales else STUDY_SCALES
        windows_study(clips, scales, parse_bands(args.bands) if args.bands else None, args.model)
    if args.pipeline:
        pipeline_study(clips, parse_bands(args.bands) if args.bands else None, args.verbose,
                       None if args.horizon == "off" else "auto" if args.horizon == "auto" else float(args.horizon))
    if args.cost:
        cost_study()
    if not (args.windows or args.pipeline or args.cost):
        ap.error("give --windows, --pipeline and / or --cost")


if __name__ == "__main__":
    main()

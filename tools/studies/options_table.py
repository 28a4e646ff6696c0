"""Every off-by-default pipeline option, alone and combined, on every annotated clip (run by hand;
docs/accuracy.md "Every option on every clip, today").

A *setting* is ``base`` (today's defaults) or option names joined by ``+`` (``noown+pfilter``;
the small-vehicle and side-view components, the large-vehicle search and the perspective stage
(``persp``: ``--perspective``) and the perspective filter (``pfilter``: ``--perspective-filter``) it
also measured were deleted: docs/accuracy.md, "Deleted stages"):

- ``split``: ``--split-neighbours`` (the default since this table was measured: a no-op today);
  ``nosplit``: ``--no-split-neighbours``; ``own``: ``--own-vehicle`` (the default now, a no-op);
  ``noown``: ``--no-own-vehicle``; ``both``: ``--traffic both``.

Each setting runs on every clip as ``fastdet eval --all`` runs it (:func:`tools.studies.loo.run_clip`)
twice:

- *in-sample*: the bundled models, as ``fastdet eval --all`` (the bundled box regressor saw the clips);
- *held out* (``--loo DIR``): each clip's box regressor fitted without it, ``DIR/refine_without_CLIP.npz``
  (``python -m tools.studies.refine_loo --out-dir DIR``).

Cost: HOG cells and windows of a full scan of a 1280x720 frame at the reference horizon, every
model's bands (:func:`search_cost`), as a ratio of today's; options that change no band are 1.00x.

A setting *holds* when, held out, no clip's F1 falls below today's (to 0.005), both Udacity clips
stay >= 0.90, and its HOG cells and scoring multiply-adds are at most 1.3x today's (:func:`holds`).

Results are kept in ``--out-dir`` (``cost.json``, ``in.json``, ``loo.json``) as they come (a rerun
skips what is there; ``--tables-only`` prints them).

    python -m tools.studies.options_table --out-dir /tmp/s3-combos --loo /tmp/s3-combos-loo \\
        [--settings base,noown,pfilter] [--clips A,B] [--no-in-sample]
"""
from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from fastdet.config import NeighbourSplit, OwnVehicleConfig, PipelineConfig
from fastdet.eval.clips import AnnotatedClip, ClipScore, annotated_clips
from fastdet.io.atomic import write_bytes
from fastdet.video import make_detector
from tools.studies.band_cost import scan_cost
from tools.studies.loo import SAME_CAMERA, run_clip

#: option name -> (the CLI flag it stands for, what it does to a PipelineConfig)
OPTIONS: dict[str, tuple[str, Callable[[PipelineConfig], PipelineConfig]]] = {
    "split": ("--split-neighbours", lambda c: replace(c, split=NeighbourSplit())),
    "nosplit": ("--no-split-neighbours", lambda c: replace(c, split=None)),
    "own": ("--own-vehicle", lambda c: replace(c, own_vehicle=OwnVehicleConfig())),
    "noown": ("--no-own-vehicle", lambda c: replace(c, own_vehicle=None)),
    "both": ("--traffic both", lambda c: replace(c, traffic="both")),
}

#: every option alone
DEFAULT_SETTINGS = ("base", *OPTIONS)

#: the result files of an --out-dir (:func:`load`)
KEYS = ("cost", "in", "loo")
#: a setting holds only at or under this cost (HOG cells and scoring multiply-adds of a full scan, x today's)
MAX_COST = 1.3
#: the two Udacity clips must stay at or above this F1
UDACITY_FLOOR = 0.90
#: an F1 this much under today's is a fall
TOLERANCE = 0.005


def parse_setting(name: str) -> tuple[str, ...]:
    """The option names of a setting (``()`` for ``base``); ValueError for an unknown option,
    or one named twice."""
    if name == "base":
        return ()
    opts = tuple(name.split("+"))
    bad = [o for o in opts if o not in OPTIONS]
    if bad:
        raise ValueError(f"unknown option {bad[0]!r} in {name!r} (options: base, {', '.join(OPTIONS)})")
    if len(set(opts)) != len(opts):
        raise ValueError(f"an option named twice in {name!r}")
    for on, off in (("split", "nosplit"), ("own", "noown")):
        if on in opts and off in opts:
            raise ValueError(f"{name!r}: {on} and {off}")
    return opts


def config_for(setting: str, refine_model: str | None = None) -> PipelineConfig:
    """The pipeline of ``setting`` (today's defaults plus its options); ``refine_model``: a
    held-out box regressor in place of the bundled one."""
    config = PipelineConfig(refine_model=refine_model)
    opts = parse_setting(setting)
    for o in opts:
        config = OPTIONS[o][1](config)
    return config


def search_cost(config: PipelineConfig, shape: tuple[int, int] = (720, 1280)) -> dict[str, float]:
    """HOG cells, windows and scoring multiply-adds of a full scan of a ``shape`` frame at the reference horizon, over
    every model's bands (main, oncoming)."""
    return scan_cost(make_detector(replace(config, horizon=None)), shape)


def held_out_model(clip: str, loo: Path) -> str:
    """The box regressor that never saw ``clip``; SystemExit naming it when missing."""
    refine = loo / f"refine_without_{clip}.npz"
    if not refine.is_file():
        raise SystemExit(f"options_table: {refine} missing (see the module docstring for how it is built)")
    return str(refine)


def summary_of(score: ClipScore) -> dict[str, Any]:
    """The figures the tables show of one clip's score."""
    r = score.result
    return {"p": r.precision, "r": r.recall, "f1": r.f1, "fa": r.fp_per_frame, "tp": r.tp, "fp": r.fp,
            "targets": r.num_gt, "widths": [[b.found, b.total] for b in score.widths]}


def holds(loo_f1: dict[str, float], base_f1: dict[str, float], cost: dict[str, float],
          udacity: Sequence[str] = SAME_CAMERA[0]) -> tuple[bool, str]:
    """Whether a setting holds (module docstring) and, if not, the first reason."""
    for clip, f in base_f1.items():
        if clip not in loo_f1:
            return False, f"{clip} not measured"
        if loo_f1[clip] < f - TOLERANCE:
            return False, f"{clip} {f:.2f} -> {loo_f1[clip]:.2f}"
    for clip in udacity:
        if clip in loo_f1 and loo_f1[clip] < UDACITY_FLOOR:
            return False, f"{clip} {loo_f1[clip]:.2f} < {UDACITY_FLOOR}"
    for k in ("hog_cells", "score_macs"):
        if cost[k] > MAX_COST:
            return False, f"{k} {cost[k]:.2f}x"
    return True, "holds"


def _cell(s: dict[str, Any]) -> str:
    return f"{s['f1']:.2f} ({s['p']:.2f}/{s['r']:.2f}, {s['fa']:.2f})"


def _widths(s: dict[str, Any]) -> str:
    return ", ".join(f"{f}/{t}" if t else "-" for f, t in s["widths"])


def tables(results: dict[str, Any], settings: Sequence[str], clips: Sequence[str]) -> str:
    """The markdown tables: a summary (cost, held-out F1 per clip, holds?) and, per mode, F1 (P/R,
    false alarms a frame) and hits by width per clip."""
    out = []
    base_cost = results["cost"].get("base")
    base_loo = {c: results["loo"]["base"][c]["f1"] for c in clips if c in results["loo"].get("base", {})}
    head = ["setting", "flags", "HOG cells", "windows", "scoring MACs", *clips, "holds?"]
    out += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for s in settings:
        cost = results["cost"].get(s)
        ratio = {k: cost[k] / base_cost[k] for k in cost} if cost and base_cost else None
        loo = results["loo"].get(s, {})
        flags = " ".join(OPTIONS[o][0] for o in parse_setting(s)) or "(today)"
        f1 = {c: loo[c]["f1"] for c in clips if c in loo}
        verdict = holds(f1, base_loo, ratio)[1] if ratio and s != "base" and base_loo else "-"
        if verdict == "holds" and all(abs(f1[c] - base_loo[c]) <= TOLERANCE for c in base_loo):
            verdict = "holds (no change)"
        row = [s, flags, *(f"{ratio[k]:.2f}x" if ratio else "?" for k in ("hog_cells", "windows", "score_macs"))]
        row += [f"{f1[c]:.2f}" if c in f1 else "?" for c in clips]
        out.append("| " + " | ".join(row + [verdict]) + " |")
    for mode, title in (("loo", "held out (leave one clip out)"), ("in", "in-sample (as `fastdet eval --all`)")):
        if not results.get(mode):
            continue
        out += ["", f"{title}: F1 (P/R, false alarms a frame); hits by width < 60 / 60-120 / >= 120", ""]
        head = ["setting", *clips]
        out += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for s in settings:
            res = results[mode].get(s, {})
            out.append("| " + " | ".join([s] + [f"{_cell(res[c])}; {_widths(res[c])}" if c in res else "?"
                                                 for c in clips]) + " |")
    return "\n".join(out)


def _save(part: dict[str, Any], path: Path) -> None:
    write_bytes(path, json.dumps(part, indent=1).encode())


def load(out_dir: Path) -> dict[str, Any]:
    """What ``out_dir`` holds: ``{"cost": {setting: ...}, "in": {setting: {clip: ...}}, "loo": ...}``
    (one JSON file each, so an in-sample and a held-out run may go on side by side)."""
    results: dict[str, Any] = {}
    for key in KEYS:
        path = out_dir / f"{key}.json"
        results[key] = json.loads(path.read_text()) if path.is_file() else {}
    return results


def run(settings: Sequence[str], clips: Sequence[AnnotatedClip], out_dir: Path, loo: Path | None,
        in_sample: bool = True) -> dict[str, Any]:
    """Measure every setting (module docstring), keeping ``out_dir/{cost,in,loo}.json`` up to date
    (a rerun skips what they hold)."""
    results = load(out_dir)
    for s in settings:
        if s not in results["cost"]:
            results["cost"][s] = search_cost(config_for(s))
            _save(results["cost"], out_dir / "cost.json")
        modes = (["in"] if in_sample else []) + (["loo"] if loo is not None else [])
        for mode in modes:
            for clip in clips:
                done = results[mode].setdefault(s, {})
                if clip.name in done:
                    continue
                if mode == "loo":
                    assert loo is not None
                    config = config_for(s, held_out_model(clip.name, loo))
                else:
                    config = config_for(s)
                done[clip.name] = summary_of(run_clip(clip, config))
                _save(results[mode], out_dir / f"{mode}.json")
                print(f"{s} {mode} {clip.name}: {_cell(done[clip.name])}", flush=True)
    return results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", type=Path, required=True, help="the result files go here (a rerun resumes)")
    ap.add_argument("--loo", type=Path, default=None, help="the held-out box regressors (refine_loo --out-dir)")
    ap.add_argument("--settings", default=",".join(DEFAULT_SETTINGS), help="comma-separated settings")
    ap.add_argument("--clips", default=None, help="comma-separated clips (default: every annotated clip)")
    ap.add_argument("--no-in-sample", action="store_true", help="only the held-out runs")
    ap.add_argument("--tables-only", action="store_true", help="print the tables of --out-dir's results, run nothing")
    a = ap.parse_args(argv)
    settings = a.settings.split(",")
    try:
        for s in settings:
            parse_setting(s)
    except ValueError as exc:
        print(f"options_table: {exc}", file=sys.stderr)
        return 2
    if "base" not in settings:
        settings.insert(0, "base")
    clips = annotated_clips()
    if a.clips:
        want = a.clips.split(",")
        clips = [c for c in clips if c.name in want]
    a.out_dir.mkdir(parents=True, exist_ok=True)
    if a.tables_only:
        results = load(a.out_dir)
    else:
        results = run(settings, clips, a.out_dir, a.loo, not a.no_in_sample)
    print(tables(results, settings, [c.name for c in clips]))
    return 0


if __name__ == "__main__":
    sys.exit(main())

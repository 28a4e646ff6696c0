"""Command-line options shared by several subcommands."""
from __future__ import annotations

import argparse

from ..config import (
    HeatConfig,
    NeighbourSplit,
    OwnVehicleConfig,
    PerspectiveConfig,
    PipelineConfig,
    PlausibleConfig,
    SelfCalibration,
)
from ..errors import FastdetError


def positive_int(s: str) -> int:
    """argparse type: an int >= 1."""
    v = int(s)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {v}")
    return v


def nonneg_int(s: str) -> int:
    """argparse type: an int >= 0."""
    v = int(s)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {v}")
    return v


def positive_float(s: str) -> float:
    """argparse type: a finite float > 0."""
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {s!r}") from None
    if not (v > 0 and v != float("inf")):
        raise argparse.ArgumentTypeError(f"must be > 0, got {s}")
    return v


def fraction(s: str) -> float:
    """argparse type: a number in [0, 1]."""
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 1], got {s!r}") from None
    if not 0 <= v <= 1:
        raise argparse.ArgumentTypeError(f"expected a fraction in [0, 1], got {s!r}")
    return v


def horizon_value(s: str) -> float | str | None:
    """argparse type of ``--horizon``: ``auto`` (estimate it from the video), ``off`` (the
    search bands as configured, for 1280x720 footage with the horizon at 0.585 of the height)
    or the horizon row as a fraction of the frame height, in [0, 1]."""
    if s in ("auto", "off"):
        return None if s == "off" else "auto"
    try:
        return fraction(s)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"'auto', 'off' or a fraction of the frame height in [0, 1], "
                                         f"got {s!r}") from None


def add_horizon_argument(parser: argparse.ArgumentParser) -> None:
    """``--horizon auto|off|F``, shared by ``video``, ``eval`` and ``batch``."""
    parser.add_argument("--horizon", type=horizon_value, default="auto", metavar="auto|off|F",
                        help="where the search bands go: 'auto' (default) follows the horizon estimated "
                             "from the first seconds of the video; F: the horizon row as a fraction of the "
                             "frame height (another camera's known horizon); 'off': bands as configured")
    parser.add_argument("--perspective", action="store_true",
                        help="the search bands follow the horizon and the camera's ratio (vehicle width / how "
                             "far below the horizon it stands) that the tracked vehicles show (off by default; "
                             "docs/geometry.md)")


def add_search_argument(parser: argparse.ArgumentParser) -> None:
    """``--full-search``, shared by ``video``, ``eval``, ``bench`` and ``batch``."""
    parser.add_argument("--full-search", action="store_true",
                        help="score every window of every band on every frame (default: every window every "
                             "5 frames and after a cut or a lost track; in between only near the tracked "
                             "vehicles and recent detections, plus a rotating strip)")


def add_oncoming_arguments(parser: argparse.ArgumentParser) -> None:
    """``--oncoming-model`` / ``--no-oncoming``, ``--traffic``, ``--side`` / ``--side-model`` and
    ``--small`` / ``--small-model``, shared by ``video``, ``eval``, ``bench`` and ``batch``."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--oncoming-model", metavar="WIDE.npz", default=None,
                   help="wide-window model for oncoming traffic above the median "
                        "(default: the bundled one; trained with `train --window-rows`)")
    g.add_argument("--no-oncoming", action="store_true",
                   help="no wide-window model: only the main model's square windows")
    parser.add_argument("--traffic", choices=("right", "left", "both"), default="right",
                        help="the side of the road traffic drives on, which puts the oncoming cars on the "
                             "other side of the view: 'right' (default; oncoming cars on the left), 'left' "
                             "(UK, Japan, India, Australia ...: searched on the right), 'both' (the whole "
                             "width, about 15%% more CPU a frame)")
    s = parser.add_mutually_exclusive_group()
    s.add_argument("--side", action="store_true",
                   help="add the bundled side-view component (fastdet/models/side.npz: 64x32 windows for "
                        "vehicles wider than tall, parked cars seen from the side; docs/components.md); off "
                        "by default")
    s.add_argument("--side-model", metavar="SIDE.npz", default=None,
                   help="add this side-view component (built by `python -m tools.scripts.side_model`)")
    m = parser.add_mutually_exclusive_group()
    m.add_argument("--small", action="store_true",
                   help="add the bundled small-vehicle component (fastdet/models/small.npz: 32x32 windows on the "
                        "frame at its own resolution about the horizon, for vehicles under 60 px wide of 1280; "
                        "docs/components.md); off by default")
    m.add_argument("--small-model", metavar="SMALL.npz", default=None,
                   help="add this small-vehicle component (built by `python -m tools.scripts.small_model`)")


def add_refine_argument(parser: argparse.ArgumentParser) -> None:
    """``--no-refine``, shared by ``video``, ``eval``, ``bench`` and ``batch``."""
    parser.add_argument("--no-refine", action="store_true",
                        help="report the heat map's boxes as they are, without the learned box refinement "
                             "(fastdet/models/refine_cameras.npz, applied 3 times)")


def add_camera_arguments(parser: argparse.ArgumentParser) -> None:
    """``--no-own-vehicle`` / ``--own-vehicle``, ``--no-split-neighbours`` / ``--split-neighbours`` and
    ``--perspective-filter``: the optional stages for other cameras."""
    o = parser.add_mutually_exclusive_group()
    o.add_argument("--no-own-vehicle", action="store_true",
                   help="search the own vehicle's picture regions too, instead of dropping the windows lying on "
                        "what stays fixed at the picture's border while the scene moves in the first 3 s (hood, "
                        "dashboard, mirrors, letterbox bars: the default)")
    o.add_argument("--own-vehicle", action="store_true",
                   help="drop the windows lying on the own vehicle (the default; kept for scripts that name it)")
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--no-split-neighbours", action="store_true",
                   help="keep a wide heat blob whole (one box over vehicles side by side) instead of splitting it "
                        "between the modes of its windows, one box per vehicle (the default)")
    g.add_argument("--split-neighbours", action="store_true",
                   help="split a wide heat blob between the modes of its windows (the default; kept for scripts "
                        "that name it)")
    parser.add_argument("--perspective-filter", action="store_true",
                        help="drop the boxes whose width no vehicle and no camera can have for how far below the "
                             "horizon they stand (too narrow: 0.45x those rows, too wide: 12x); off by default")
    parser.add_argument("--self-calibrate", action="store_true",
                        help="move the main model's decision values per video so that 10%% of the windows of its "
                             "first 5 full scans reach the level the bundled model's reach on a typical camera "
                             "(no labels; docs/training.md, 'Operating point from the video itself'); off by default")


def pipeline_config(args: argparse.Namespace) -> PipelineConfig:
    """The :class:`~fastdet.config.PipelineConfig` of parsed CLI arguments, for every command
    that runs the pipeline (``video``, ``eval --video``, ``bench``, ``batch``); an option a
    command does not have takes its default. ``--no-track``: no tracker (and so the full
    search); ``--full-search``: no guided search; ``--no-refine``: no refinement;
    ``--heat-frames`` / ``--heat-decay`` / ``--heat-threshold``: the main heat map (a bad
    value: :class:`~fastdet.errors.FastdetError`); ``--no-own-vehicle``: the own-vehicle stage off;
    ``--no-split-neighbours``: the neighbour split off; ``--perspective-filter``: the perspective test of the
    plausibility stage on; ``--self-calibrate``: the main model's operating point set from the video."""
    d = HeatConfig()
    try:
        heat = HeatConfig(n_frames=getattr(args, "heat_frames", d.n_frames), decay=getattr(args, "heat_decay", d.decay),
                          threshold=getattr(args, "heat_threshold", d.threshold))
    except ValueError as exc:
        raise FastdetError(f"heat map: {exc}") from None
    config = PipelineConfig(model=getattr(args, "model", None),
                            oncoming=False if getattr(args, "no_oncoming", False)
                            else (getattr(args, "oncoming_model", None) or True),
                            side=getattr(args, "side_model", None) or bool(getattr(args, "side", False)),
                            small=getattr(args, "small_model", None) or bool(getattr(args, "small", False)),
                            traffic=getattr(args, "traffic", "right"), horizon=getattr(args, "horizon", "auto"),
                            heat=heat, perspective=PerspectiveConfig() if getattr(args, "perspective", False) else None,
                            own_vehicle=None if getattr(args, "no_own_vehicle", False) else OwnVehicleConfig(),
                            split=None if getattr(args, "no_split_neighbours", False) else NeighbourSplit(),
                            plausible=PlausibleConfig(perspective=bool(getattr(args, "perspective_filter", False))),
                            selfcal=SelfCalibration() if getattr(args, "self_calibrate", False) else None)
    off = [name for name, flag in (("tracker", "no_track"), ("guided", "full_search"), ("refine", "no_refine"))
           if getattr(args, flag, False)]
    return config.without(*off)  # type: ignore[arg-type]

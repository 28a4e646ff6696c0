"""Command-line options shared by several subcommands."""
from __future__ import annotations

import argparse

from ..config import (
    BOXES,
    HeatConfig,
    NeighbourSplit,
    OwnVehicleConfig,
    PipelineConfig,
)
from ..errors import DataError, FastdetError


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


#: an argparse parser or argument group: what the ``add_*`` functions below add options to
Options = argparse._ActionsContainer


def add_horizon_argument(parser: Options) -> None:
    """``--horizon auto|off|F``, shared by ``video``, ``eval`` and ``batch``."""
    parser.add_argument("--horizon", type=horizon_value, default="auto", metavar="auto|off|F",
                        help="the horizon: estimated, none, or at F x height")


def add_search_argument(parser: Options) -> None:
    """``--full-search``, shared by ``video``, ``eval``, ``bench`` and ``batch``."""
    parser.add_argument("--full-search", action="store_true",
                        help="score every window on every frame")


def add_oncoming_arguments(parser: Options) -> None:
    """``--oncoming-model`` / ``--no-oncoming`` and ``--traffic``, shared by ``video``, ``eval``,
    ``bench`` and ``batch``."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--oncoming-model", metavar="WIDE.npz", default=None,
                   help="oncoming-traffic model (default: bundled)")
    g.add_argument("--no-oncoming", action="store_true", help="no oncoming-traffic model")
    parser.add_argument("--traffic", choices=("right", "left", "both"), default="right",
                        help="the side traffic drives on (default right)")


def add_boxes_argument(parser: Options) -> None:
    """``--boxes-from heat|nms``, shared by ``video``, ``eval``, ``bench`` and ``batch``."""
    parser.add_argument("--boxes-from", choices=BOXES, default=None,
                        help="one box per vehicle from the heat map over frames or from each frame's windows "
                             "(default: what the model records, fastdet adapt's choice; else heat)")


def add_refine_argument(parser: Options) -> None:
    """``--no-refine``, shared by ``video``, ``eval``, ``bench`` and ``batch``."""
    parser.add_argument("--no-refine", action="store_true",
                        help="no learned box refinement")


def add_camera_arguments(parser: Options) -> None:
    """``--no-own-vehicle`` and ``--no-split-neighbours``: the stages for other cameras, off.
    ``--own-vehicle`` and ``--split-neighbours`` (the defaults, spelt out) are still accepted but
    not shown in ``--help``."""
    o = parser.add_mutually_exclusive_group()
    o.add_argument("--no-own-vehicle", action="store_true",
                   help="also search the own vehicle (hood, mirrors)")
    o.add_argument("--own-vehicle", action="store_true", help=argparse.SUPPRESS)  # the default, spelt out
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--no-split-neighbours", action="store_true",
                   help="one box over vehicles side by side")
    g.add_argument("--split-neighbours", action="store_true", help=argparse.SUPPRESS)  # the default, spelt out


def pipeline_groups(parser: argparse.ArgumentParser) -> tuple[Options, Options, Options]:
    """The ``search``, ``tracking`` and ``advanced`` option groups of a command that runs the
    pipeline, with the shared options added (``video``, ``eval``, ``bench``, ``batch``);
    ``horizon``: with ``--horizon`` (not ``bench``)."""
    search = parser.add_argument_group("models and search")
    tracking = parser.add_argument_group("tracking")
    advanced = parser.add_argument_group("advanced")
    search.add_argument("--model", metavar="MODEL.npz", help="main model (default: the bundled one)")
    add_oncoming_arguments(search)
    add_search_argument(advanced)
    add_boxes_argument(advanced)
    add_refine_argument(advanced)
    add_camera_arguments(advanced)
    return search, tracking, advanced


def pipeline_config(args: argparse.Namespace) -> PipelineConfig:
    """The :class:`~fastdet.config.PipelineConfig` of parsed CLI arguments, for every command
    that runs the pipeline (``video``, ``eval --video``, ``bench``, ``batch``); an option a
    command does not have takes its default. ``--no-track``: no tracker (and so the full
    search); ``--full-search``: no guided search; ``--no-refine``: no refinement;
    ``--heat-frames`` / ``--heat-decay`` / ``--heat-threshold``: the main heat map (a bad
    value: :class:`~fastdet.errors.FastdetError`); ``--no-own-vehicle``: the own-vehicle stage off;
    ``--no-split-neighbours``: the neighbour split off; ``--boxes-from``: the box formation."""
    d = HeatConfig()
    try:
        heat = HeatConfig(n_frames=getattr(args, "heat_frames", d.n_frames), decay=getattr(args, "heat_decay", d.decay),
                          threshold=getattr(args, "heat_threshold", d.threshold))
    except ValueError as exc:
        raise FastdetError(f"heat map: {exc}") from None
    config = PipelineConfig(model=getattr(args, "model", None),
                            oncoming=False if getattr(args, "no_oncoming", False)
                            else (getattr(args, "oncoming_model", None) or True),
                            traffic=getattr(args, "traffic", "right"), horizon=getattr(args, "horizon", "auto"),
                            heat=heat, boxes=getattr(args, "boxes_from", None),
                            own_vehicle=None if getattr(args, "no_own_vehicle", False) else OwnVehicleConfig(),
                            split=None if getattr(args, "no_split_neighbours", False) else NeighbourSplit())
    off = [name for name, flag in (("tracker", "no_track"), ("guided", "full_search"), ("refine", "no_refine"))
           if getattr(args, flag, False)]
    return config.without(*off)  # type: ignore[arg-type]


def teacher_size(s: str) -> int:
    """argparse type of ``--size``: whole px from 32 to 4096."""
    from ..config.teacher import MAX_TEACHER_SIZE, MIN_TEACHER_SIZE

    try:
        v = int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of px, got {s!r}") from None
    if not MIN_TEACHER_SIZE <= v <= MAX_TEACHER_SIZE:
        raise argparse.ArgumentTypeError(f"must be from {MIN_TEACHER_SIZE} to {MAX_TEACHER_SIZE} px, got {v}")
    return v


def video_files(source: str) -> list[str]:
    """The video files of VIDEO|DIR (a folder: its video files by name, sorted)."""
    import os

    from ..batch.inputs import is_video_name  # a table of extensions; no Dask imported
    from ..io.reader import check_source

    if not os.path.isdir(source):
        check_source(source)
        return [source]
    found = sorted(os.path.join(source, f) for f in os.listdir(source)
                   if not f.startswith(".") and is_video_name(f) and os.path.isfile(os.path.join(source, f)))
    if not found:
        raise DataError(f"{source}: no video files in this folder")
    return found

"""``python -m fastdet batch``: many videos, one Dask task each (see :mod:`fastdet.batch`).

``python -m fastdet batch INPUT... --out DIR [--video] [--json] [--model M.npz]
[--oncoming-model W.npz | --no-oncoming] [--no-track] [--workers N] [--scheduler tcp://host:8786]
[--resume | --overwrite] [--retries N] [--table boxes.parquet|boxes.csv] [--no-progress]``

- INPUT: video files, folders (searched recursively for videos), quoted glob patterns, or
  ``.txt`` list files of paths (:mod:`fastdet.batch.inputs`).
- For each video, in DIR: ``NAME.boxes.txt`` (MOTChallenge with track ids, byte-identical to
  ``fastdet video --boxes``; ``--no-track`` as ``video --no-track``), with ``--json``
  ``NAME.boxes.jsonl``, with ``--video`` ``NAME.annotated.mp4``;
  ``DIR/manifest.jsonl`` records every finished video.
- Exit status: 0 when every video is done (or was already), 1 when some failed (listed in
  the summary), 2 for bad arguments (one line), 128 + N after signal N (the finished videos
  are kept: rerun to do the rest).
- Dask is an optional extra: without it the command says ``pip install fastdet[cluster]``.
"""
from __future__ import annotations

import argparse
import importlib
import os
from pathlib import Path
from types import ModuleType

from ..config.batch import BatchOptions
from ..errors import FastdetError
from ..io.paths import check_outside_package, check_paths
from ..signals import Stopped
from ._args import add_horizon_argument, nonneg_int, pipeline_config, pipeline_groups, positive_int

_INSTALL = "pip install fastdet[cluster]"
# the packages of the ``cluster`` extra that fastdet.batch imports
_CLUSTER_MODULES = {"dask", "distributed", "pyarrow"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.usage = "%(prog)s INPUT... --out DIR [--video] [--json] [options]"
    io = parser.add_argument_group("inputs and outputs")
    io.add_argument("inputs", nargs="+", metavar="INPUT", help="videos, folders, quoted globs or .txt lists")
    io.add_argument("-o", "--out", required=True, metavar="DIR",
                    help="output folder: NAME.boxes.txt, manifest.jsonl")
    io.add_argument("--video", action="store_true", help="also NAME.annotated.mp4")
    io.add_argument("--json", action="store_true", help="also NAME.boxes.jsonl")
    io.add_argument("--table", metavar="BOXES.parquet", help="also one table of all boxes (.parquet, .csv)")
    io.add_argument("--no-progress", action="store_true", help="one line per video, no progress bar")
    cluster = parser.add_argument_group("cluster")
    cluster.add_argument("--workers", type=positive_int, default=None, metavar="N",
                         help="local cluster's processes (default: cores)")
    cluster.add_argument("--scheduler", metavar="ADDRESS", default=None,
                         help="a Dask scheduler, e.g. tcp://host:8786")
    g = cluster.add_mutually_exclusive_group()
    g.add_argument("--resume", dest="overwrite", action="store_false",
                   help="skip videos already done (the default)")
    g.add_argument("--overwrite", dest="overwrite", action="store_true", help="redo every video")
    parser.set_defaults(overwrite=False)
    cluster.add_argument("--retries", type=nonneg_int, default=2, metavar="N",
                         help="extra attempts of a failed task (default 2)")
    search, tracking, _ = pipeline_groups(parser)
    add_horizon_argument(search)
    tracking.add_argument("--no-track", action="store_true", help="no tracker: boxes without ids (-1)")


def _batch_modules() -> tuple[ModuleType, ...]:
    """``fastdet.batch.job``, ``.inputs``, ``.settings`` and ``.table``, imported here and not
    at the top: they need the optional ``cluster`` extra, and ``--help`` must work without it."""
    try:
        return tuple(importlib.import_module(f"fastdet.batch.{m}") for m in ("job", "inputs", "settings", "table"))
    except ImportError as exc:
        if (exc.name or "").split(".")[0] in _CLUSTER_MODULES:
            raise FastdetError(f"`batch` runs on Dask, which is not installed ({exc.name}): {_INSTALL}") from None
        raise


def run(args: argparse.Namespace) -> int:
    """The ``batch`` subcommand."""
    job, inputs, settings_mod, table_mod = _batch_modules()
    scheduler = args.scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS") or None
    if scheduler and args.workers:
        raise FastdetError("--workers is for the local cluster; with --scheduler the cluster's workers run the tasks")
    table = Path(args.table) if args.table else None
    if table is not None:
        table_mod.table_format(table)
    out_dir = Path(args.out)
    check_outside_package(out_dir, "--out")  # before the folder is made
    if table is not None:
        check_outside_package(table, "--table")
    writes = inputs.batch_writes(out_dir, settings_mod.SUFFIXES.values(),
                                 [out_dir / settings_mod.MANIFEST_NAME, *([table] if table is not None else [])])
    videos = inputs.expand_inputs(args.inputs, writes)
    pipeline = pipeline_config(args)
    settings = settings_mod.checked_settings(pipeline, video=args.video, json=args.json)
    if scheduler:
        job.check_address(scheduler)
    with job.out_dir_for_run(out_dir):  # a failed start leaves no folder it made
        if table is not None:  # after the output folder exists: the table may go into it
            check_paths([("--model", args.model), ("--oncoming-model", args.oncoming_model),
                         *[("INPUT", v) for v in videos]], [("--table", table, "table")])
            if os.path.realpath(table.parent) == os.path.realpath(out_dir) \
                    and table.name.endswith(tuple(settings_mod.SUFFIXES.values())):
                raise FastdetError(f"--table {table}: is a name the batch gives a video's outputs; choose another")
        opts = BatchOptions(out_dir=Path(args.out), settings=settings, workers=args.workers, scheduler=scheduler,
                            overwrite=args.overwrite, retries=args.retries, table=table, progress=not args.no_progress)
        try:
            report = job.run_batch(videos, opts)
        except job.BatchInterrupted as exc:  # the dispatcher's one line, with what was done
            raise Stopped(exc.signum, f"{exc.done} video(s) done in this run, {exc.stopped} stopped (no output kept); "
                                      f"run the same command again to do the rest") from None
    print(job.format_summary(report), flush=True)
    if report.table_rows is not None:
        print(f"table: {table} ({report.table_rows} boxes)", flush=True)
    return 1 if report.failed else 0

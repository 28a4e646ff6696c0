"""What a batch video's outputs depend on (:class:`~fastdet.config.batch.Settings`, defined
with the other settings in :mod:`fastdet.config.batch`), checking them before any work
(:func:`check`), whether the main model carries its own box regressor
(:func:`carries_regressor`) and what the outputs are called (:func:`output_paths`)."""
from __future__ import annotations

import os
from pathlib import Path

from ..config import PipelineConfig
from ..config.batch import Settings, file_sha256
from ..video.detector import make_detector
from ..video.refine import carried_regressor_for, regressor_for

__all__ = ["MANIFEST_NAME", "SUFFIXES", "Settings", "carries_regressor", "check", "max_name_length", "file_sha256",
           "output_paths"]

#: output kind -> file name suffix after the video's output name
SUFFIXES = {"boxes": ".boxes.txt", "json": ".boxes.jsonl", "video": ".annotated.mp4"}
MANIFEST_NAME = "manifest.jsonl"


def max_name_length(out_dir: str | os.PathLike) -> int:
    """The longest output name (:func:`~fastdet.batch.inputs.output_names`) whose files, with
    the longest suffix, fit the file system of ``out_dir`` (its ``NAME_MAX``)."""
    from ..io.paths import name_max

    return max(16, name_max(out_dir) - max(len(s) for s in SUFFIXES.values()))


def carries_regressor(pipeline: PipelineConfig) -> bool:
    """Whether ``pipeline`` refines with the box regressor its main model file carries (a model
    ``fastdet adapt`` made; no regressor file named): :meth:`Settings.create`'s ``refine_carried``."""
    if pipeline.refine is None or pipeline.model is None or not os.path.isfile(pipeline.model):
        return False  # a missing file: Settings.create says so, in its words
    return carried_regressor_for(pipeline.model, pipeline.refine_model) is not None


def check(settings: Settings) -> None:
    """Load the models as a worker will: :class:`~fastdet.errors.ModelError` (one line) now,
    before any work, for a file that is not a model or a wide model that is not one."""
    pipeline = settings.pipeline
    detector = make_detector(pipeline)
    if pipeline.refine is not None:  # a carried regressor comes out of the model the detector loaded
        regressor_for(detector.model, pipeline.refine_model, name=pipeline.model)


def output_paths(out_dir: str | os.PathLike, name: str, settings: Settings) -> dict[str, Path]:
    """Final output files of the video called ``name``: kind -> path, for ``settings.kinds``."""
    d = Path(out_dir)
    return {kind: d / f"{name}{SUFFIXES[kind]}" for kind in settings.kinds}

"""What a batch video's outputs depend on (:class:`~fastdet.config.batch.Settings`, defined
with the other settings in :mod:`fastdet.config.batch`), checking them before any work
(:func:`check`), whether the main model carries its own box regressor
(:func:`carries_regressor`) and what the outputs are called (:func:`output_paths`)."""
from __future__ import annotations

import os
from pathlib import Path

from ..config import PipelineConfig
from ..config.batch import Settings, file_sha256
from ..model import load_model
from ..video.detector import make_detector
from ..video.refine import regressor_for

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
    if pipeline.refine is None or pipeline.refine_model is not None or pipeline.model is None:
        return False
    if not os.path.isfile(pipeline.model):
        return False  # Settings.create says it is missing, in its words
    return load_model(pipeline.model).regressor is not None


def check(settings: Settings) -> None:
    """Load the models as a worker will: :class:`~fastdet.errors.ModelError` (one line) now,
    before any work, for a file that is not a model or a wide model that is not one."""
    make_detector(settings.pipeline)
    if settings.pipeline.refine is not None:
        regressor_for(settings.pipeline.model, settings.pipeline.refine_model)


def output_paths(out_dir: str | os.PathLike, name: str, settings: Settings) -> dict[str, Path]:
    """Final output files of the video called ``name``: kind -> path, for ``settings.kinds``."""
    d = Path(out_dir)
    return {kind: d / f"{name}{SUFFIXES[kind]}" for kind in settings.kinds}

"""What a batch video's outputs depend on (:class:`~fastdet.config.batch.Settings`, defined
with the other settings in :mod:`fastdet.config.batch`), made with their models loaded once
before any work (:func:`checked_settings`: whether the main model carries its own box
regressor is read from the model the check loads) and what the outputs are called
(:func:`output_paths`)."""
from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from ..config import PipelineConfig
from ..config.batch import Settings, file_sha256
from ..video.detector import camera_horizon, make_detector
from ..video.refine import carried_regressor_for, regressor_for

__all__ = ["MANIFEST_NAME", "SUFFIXES", "Settings", "checked_settings", "max_name_length", "file_sha256",
           "output_paths"]

#: output kind -> file name suffix after the video's output name
SUFFIXES = {"boxes": ".boxes.txt", "json": ".boxes.jsonl", "video": ".annotated.mp4"}
MANIFEST_NAME = "manifest.jsonl"


def max_name_length(out_dir: str | os.PathLike) -> int:
    """The longest output name (:func:`~fastdet.batch.inputs.output_names`) whose files, with
    the longest suffix, fit the file system of ``out_dir`` (its ``NAME_MAX``)."""
    from ..io.paths import name_max

    return max(16, name_max(out_dir) - max(len(s) for s in SUFFIXES.values()))


def checked_settings(pipeline: PipelineConfig | None = None, video: bool = False,
                     json: bool = False) -> Settings:
    """The batch's :class:`Settings` for ``pipeline`` (:meth:`Settings.create`'s arguments), its
    models loaded as a worker will, once, before any work: :class:`~fastdet.errors.ModelError`
    (one line) for a missing file, a file that is not a model or a wide model that is not one.
    A main model that carries its camera's box regressor (``fastdet adapt``'s; no regressor
    file named) is refined with it: the settings name no regressor file of their own. A main
    model that records no oncoming model beside it (``fastdet adapt``'s:
    :func:`~fastdet.video.detector.make_detector`) runs without the bundled one, as in
    ``video``; a record of its camera's horizon that is not one is refused here too."""
    p = pipeline if pipeline is not None else PipelineConfig()
    settings = Settings.create(p, video=video, json=json)  # a missing file: one line, in its words
    # the bundled oncoming model as `True`, so that the main model's record decides, as in `video`
    detector = make_detector(replace(settings.pipeline, oncoming=True) if p.oncoming is True else settings.pipeline)
    camera_horizon(p, detector)  # a bad record of the camera's horizon: one line now, not a failure per video
    if p.oncoming is True and detector.oncoming_model is None:
        p = replace(p, oncoming=False)
        settings = Settings.create(p, video=video, json=json)
    if p.refine is None:
        return settings
    carried = carried_regressor_for(detector.model, p.refine_model, name=settings.pipeline.model)
    if carried is not None:
        return Settings.create(p, video=video, json=json, refine_carried=True)
    regressor_for(None, settings.pipeline.refine_model)  # the named or bundled file loads
    return settings


def output_paths(out_dir: str | os.PathLike, name: str, settings: Settings) -> dict[str, Path]:
    """Final output files of the video called ``name``: kind -> path, for ``settings.kinds``."""
    d = Path(out_dir)
    return {kind: d / f"{name}{SUFFIXES[kind]}" for kind in settings.kinds}

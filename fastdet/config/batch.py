"""The settings of a batch: what every video's outputs depend on (:class:`Settings`: a
:class:`~fastdet.config.PipelineConfig`, the outputs asked for and the model files' hashes)
and how the batch runs (:class:`BatchOptions`).

The settings travel to the workers with each task (paths, not models: each worker loads a
model once, :mod:`fastdet.batch.task`) and go into the manifest with a digest; ``--resume``
skips a video only when the digest of its manifest entry is that of the current run. The
digest covers the model files' contents (SHA-256), the pipeline's settings, the outputs asked
for and the fastdet version, so a retrained model or a new release redoes the videos.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from .._version import __version__
from ..errors import ModelError, not_found
from .models import (
    DEFAULT_MODEL_PATH,
    ONCOMING_MODEL_PATH,
    REFINE_MODEL_PATH,
    resolve_model,
)
from .pipeline import PipelineConfig


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes (hex); :class:`ModelError` when it cannot be read."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    except OSError as exc:
        raise ModelError(f"{path}: cannot read ({exc.strerror or exc})") from None
    return h.hexdigest()


@dataclass(frozen=True)
class Settings:
    """The per-video settings of a batch (build with :meth:`create`).

    pipeline: the :class:`PipelineConfig`, its model files as absolute paths (``refine_model``
        ``None`` when the refinement is off or uses the regressor the main model carries).
    video, json: also write the annotated video / JSON lines (the boxes file is always written).
    model_sha256, oncoming_sha256, refine_sha256: the model files' hashes (``""`` for a model
        that is off).
    """

    pipeline: PipelineConfig
    video: bool = False
    json: bool = False
    model_sha256: str = ""
    oncoming_sha256: str = ""
    refine_sha256: str = ""

    @classmethod
    def create(cls, pipeline: PipelineConfig | None = None, video: bool = False, json: bool = False,
               refine_carried: bool = False) -> Settings:
        """Settings for ``pipeline`` (default ``PipelineConfig()``): its model files made absolute
        (``None``: the bundled ones) and hashed; :class:`ModelError` for a missing file.
        ``refine_carried``: the main model file carries its camera's box regressor
        (:func:`fastdet.batch.settings.checked_settings` finds out), which the pipeline then refines with
        when no regressor file is named: no regressor file of its own (the model's hash covers it)."""
        p = pipeline if pipeline is not None else PipelineConfig()
        main = resolve_model(p.model, DEFAULT_MODEL_PATH)
        wide = None if p.oncoming is False else resolve_model(None if p.oncoming is True else p.oncoming,
                                                               ONCOMING_MODEL_PATH)
        refine = None if p.refine is None else resolve_model(p.refine_model, REFINE_MODEL_PATH)
        if refine_carried and p.refine_model is None:
            refine = None  # the main model's own (its file, hashed below, holds it)
        for f in (main, wide, refine):
            if f is not None and not os.path.isfile(f):
                raise ModelError(str(not_found(f, f"{f}: model file not found")))
        p = replace(p, model=main, oncoming=wide if wide is not None else False, refine_model=refine)
        return cls(p, bool(video), bool(json), file_sha256(main), file_sha256(wide) if wide else "",
                   file_sha256(refine) if refine else "")

    @property
    def kinds(self) -> tuple[str, ...]:
        """The output kinds written for every video, in the order they are renamed."""
        return ("boxes",) + (("json",) if self.json else ()) + (("video",) if self.video else ())

    def record(self) -> dict[str, Any]:
        """The settings as JSON-able values (what the manifest records): the pipeline's
        (:meth:`PipelineConfig.to_dict`), the outputs, the model files' hashes and the version."""
        return {**self.pipeline.to_dict(), "outputs": list(self.kinds),
                "model_sha256": self.model_sha256, "oncoming_sha256": self.oncoming_sha256,
                "refine_sha256": self.refine_sha256, "fastdet": __version__}

    def digest(self) -> str:
        """A short hash of everything that decides the outputs' contents. The model paths
        are left out (their contents count), so moving a model file does not redo work."""
        rec = {**self.record(), **self.pipeline.digest_dict()}  # the deleted stages' fields as they were
        for k in ("model", "oncoming", "refine_model"):
            rec[k] = rec[k] is not False and rec[k] is not None  # on or off; the hashes say which file
        text = json.dumps(rec, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class BatchOptions:
    """How to run a batch. ``out_dir``: the output folder; ``settings``: every video's
    :class:`Settings`; ``workers``: local worker processes (default: the usable cores);
    ``scheduler``: address of a running Dask scheduler (then ``workers`` is unused);
    ``overwrite``: redo finished videos (default: skip them); ``retries``: extra attempts of a
    task that raised; ``table``: path of the combined table or ``None``; ``progress``: a bar."""

    out_dir: Path
    settings: Settings
    workers: int | None = None
    scheduler: str | None = None
    overwrite: bool = False
    retries: int = 2
    table: Path | None = None
    progress: bool = True

"""What a batch video's outputs depend on (:class:`Settings`) and what they are called
(:func:`output_paths`).

The settings travel to the workers with each task (paths, not models: each worker loads a
model once, :mod:`fastdet.batch.task`) and go into the manifest with a digest; ``--resume``
skips a video only when the digest of its manifest entry is that of the current run. The
digest covers the model files' contents (SHA-256), the heat-map settings, the outputs asked
for and the fastdet version, so a retrained model or a new release redoes the videos.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .._version import __version__
from ..config import GuidedSearch, HeatConfig, TrackerConfig
from ..errors import ModelError
from ..model import DEFAULT_MODEL_PATH, ONCOMING_MODEL_PATH
from ..video.pipeline import make_detector
from ..video.refine import REFINE_MODEL_PATH, load_regressor

#: output kind -> file name suffix after the video's output name
SUFFIXES = {"boxes": ".boxes.txt", "json": ".boxes.jsonl", "video": ".annotated.mp4"}
MANIFEST_NAME = "manifest.jsonl"


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
    """The per-video pipeline settings of a batch (build with :meth:`create`).

    model: absolute path of the main model file. model_sha256: its contents' hash.
    oncoming: absolute path of the wide-window (oncoming-traffic) model, or ``None`` for
        none (``--no-oncoming``). oncoming_sha256: its hash (``""`` for none).
    heat: the heat map's :class:`~fastdet.config.HeatConfig`.
    track: give the boxes track ids (the default :class:`~fastdet.config.TrackerConfig`, as
        ``fastdet video``); ``False`` as ``video --no-track`` (ids -1).
    video, json: also write the annotated video / JSON lines (the boxes file is always written).
    horizon: where the search bands go, as ``video --horizon``: ``'auto'``, a fraction of the
        frame height, or ``None`` (off).
    full_search: the exact full search on every frame (``video --full-search``) instead of the
        tracking-guided search.
    refine: the learned box refinement (the bundled regressor; ``video --no-refine``: off);
        refine_sha256: the regressor file's hash (``""`` when off).
    traffic: the side of the road traffic drives on (``video --traffic``).
    """

    model: str
    model_sha256: str
    oncoming: str | None
    oncoming_sha256: str = ""
    heat: HeatConfig = field(default_factory=HeatConfig)
    track: bool = True
    video: bool = False
    json: bool = False
    horizon: float | str | None = "auto"
    full_search: bool = False
    refine: bool = True
    refine_sha256: str = ""
    traffic: str = "right"

    @classmethod
    def create(cls, model: str | os.PathLike | None = None, oncoming: str | os.PathLike | bool = True,
               heat: HeatConfig | None = None, track: bool = True, video: bool = False,
               json: bool = False, horizon: float | str | None = "auto", full_search: bool = False,
               refine: bool = True, traffic: str = "right") -> Settings:
        """Settings for ``model`` (``None``: the bundled one) and ``oncoming`` (``True``:
        the bundled oncoming model, ``False``: none, or a path), hashing the model files."""
        main = os.path.abspath(model) if model is not None else str(DEFAULT_MODEL_PATH)
        if oncoming is True:
            wide: str | None = str(ONCOMING_MODEL_PATH)
        elif oncoming is False or oncoming is None:
            wide = None
        else:
            wide = os.path.abspath(oncoming)
        for p in (main, wide):
            if p is not None and not os.path.isfile(p):
                raise ModelError(f"{p}: model file not found")
        if traffic not in ("right", "left", "both"):
            raise ValueError(f"traffic must be 'right', 'left' or 'both', got {traffic!r}")
        return cls(main, file_sha256(main), wide, file_sha256(wide) if wide else "",
                   heat if heat is not None else HeatConfig(), bool(track), bool(video), bool(json), horizon,
                   bool(full_search), bool(refine), file_sha256(REFINE_MODEL_PATH) if refine else "", traffic)

    def check(self) -> None:
        """Load the models as a worker will: :class:`ModelError` (one line) now, before any
        work, for a file that is not a model or a wide model that is not one."""
        make_detector(self.model, self.oncoming if self.oncoming else False, self.traffic)  # type: ignore[arg-type]
        if self.refine:
            load_regressor()

    @property
    def kinds(self) -> tuple[str, ...]:
        """The output kinds written for every video, in the order they are renamed."""
        return ("boxes",) + (("json",) if self.json else ()) + (("video",) if self.video else ())

    def record(self) -> dict[str, Any]:
        """The settings as JSON-able values (what the manifest records)."""
        return {
            "model": self.model, "model_sha256": self.model_sha256,
            "oncoming": self.oncoming, "oncoming_sha256": self.oncoming_sha256,
            "heat": dataclasses.asdict(self.heat),
            "tracker": dataclasses.asdict(TrackerConfig()) if self.track else None,
            "outputs": list(self.kinds),
            "horizon": self.horizon,
            "search": "full" if self.full_search else dataclasses.asdict(GuidedSearch()),
            "refine": self.refine_sha256 if self.refine else None,
            "traffic": self.traffic,
            "fastdet": __version__,
        }

    def digest(self) -> str:
        """A short hash of everything that decides the outputs' contents. The model paths
        are left out (their contents count), so moving a model file does not redo work."""
        rec = self.record()
        del rec["model"], rec["oncoming"]
        text = json.dumps(rec, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def output_paths(out_dir: str | os.PathLike, name: str, settings: Settings) -> dict[str, Path]:
    """Final output files of the video called ``name``: kind -> path, for ``settings.kinds``."""
    d = Path(out_dir)
    return {kind: d / f"{name}{SUFFIXES[kind]}" for kind in settings.kinds}

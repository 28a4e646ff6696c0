"""The batch manifest: ``OUT/manifest.jsonl``, one JSON object per finished video.

Each line records one video's outcome when the batch learns it: ``status`` ``"done"``
(with ``frames``, ``boxes``, ``seconds``, ``fps``, the ``outputs`` and their byte
``sizes``, the input's ``input_size`` / ``input_mtime_ns``, the ``settings`` and their
``settings_hash``) or ``"failed"`` (with a one-line ``error``). A video's last line wins.

The manifest is a log, appended to and fsynced line by line (rewriting it whole after each
of thousands of videos would cost O(n^2)); a line cut short by a crash is ignored when it
is read, and the file is then rewritten without it (under a temporary name, renamed).

:meth:`Manifest.is_complete` is the ``--resume`` test: a ``done`` line with the same output
name and settings hash, an unchanged input file, and every output present at its
recorded size. :meth:`Manifest.known_failure` finds the videos that failed because of the
input itself (``permanent``: not a video, ...) with the same settings and an unchanged
file: a rerun reports them as failed again without running them.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

from ..errors import DataError
from ..io.atomic import write_bytes
from ..io.files import JsonError, parse_json, read_input_bytes


def input_stat(path: str | os.PathLike) -> dict[str, int]:
    """``input_size`` and ``input_mtime_ns`` of a file (what says "the same input")."""
    st = os.stat(path)
    return {"input_size": int(st.st_size), "input_mtime_ns": int(st.st_mtime_ns)}


def _well_formed(obj: Any) -> bool:
    """A manifest entry of the shape this module reads: an object whose ``input`` is a string
    and whose ``outputs`` / ``sizes`` / ``settings``, where present, are objects (a line whose
    ``outputs`` is a list is as damaged as one cut short)."""
    return (isinstance(obj, dict) and isinstance(obj.get("input"), str)
            and all(obj.get(k) is None or isinstance(obj[k], dict) for k in ("outputs", "sizes", "settings")))


class Manifest:
    """The manifest at ``path``: the last entry per input (``entries``) and appending."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self.entries: dict[str, dict[str, Any]] = {}
        self.dropped = 0
        self._load()

    def _load(self) -> None:
        if not self.path.exists() and not self.path.is_symlink():
            return
        data = read_input_bytes(self.path, "batch manifest")  # a FIFO, a device, a symlink loop: one line
        lines = data.split(b"\n")
        for raw in lines:
            if not raw.strip():
                continue
            try:
                obj = parse_json(raw)
            except JsonError:  # a syntax error, nesting too deep, a 5,000-digit number
                self.dropped += 1
                continue
            if _well_formed(obj):
                self.entries[obj["input"]] = obj
            else:
                self.dropped += 1
        if self.dropped or (data and not data.endswith(b"\n")):
            if self.dropped:
                print(f"fastdet batch: {self.path}: ignored {self.dropped} damaged line(s)", file=sys.stderr)
            self._rewrite()

    def _rewrite(self) -> None:
        text = "".join(json.dumps(e, separators=(",", ":")) + "\n" for e in self.entries.values())
        write_bytes(self.path, text.encode())

    def append(self, entry: dict[str, Any]) -> None:
        """Record ``entry`` (it must have ``input``): one line, flushed and fsynced."""
        line = json.dumps(entry, separators=(",", ":")) + "\n"
        try:
            with open(self.path, "a", encoding="utf-8", newline="\n") as fh:
                fh.write(line)
                fh.flush()
                os.fsync(fh.fileno())
        except OSError as exc:
            raise DataError(f"{self.path}: cannot write the manifest ({exc.strerror or exc})") from None
        self.entries[entry["input"]] = entry

    def known_failure(self, video: str | os.PathLike, name: str, settings_hash: str) -> dict[str, Any] | None:
        """The entry of ``video`` when it failed because of the input itself (``permanent``:
        not a video, frames too small, ...) with these settings and the input has not changed
        since: running it again would fail again. ``None`` otherwise."""
        e = self.entries.get(os.fspath(video))
        if not e or e.get("status") != "failed" or not e.get("permanent") or e.get("name") != name \
                or e.get("settings_hash") != settings_hash:
            return None
        try:
            same = {k: e.get(k) for k in ("input_size", "input_mtime_ns")} == input_stat(video)
        except OSError:
            return None
        return e if same else None

    def is_complete(self, video: str | os.PathLike, name: str, settings_hash: str,
                    outputs: dict[str, Path]) -> bool:
        """True when ``video`` was done as ``name`` with these settings, the input has not
        changed since, and each of ``outputs`` (kind -> final path) exists at its recorded size."""
        e = self.entries.get(os.fspath(video))
        if not e or e.get("status") != "done" or e.get("name") != name or e.get("settings_hash") != settings_hash:
            return False
        try:
            if {k: e.get(k) for k in ("input_size", "input_mtime_ns")} != input_stat(video):
                return False
            sizes = e.get("sizes") or {}
            for kind, p in outputs.items():
                if (e.get("outputs") or {}).get(kind) != p.name or sizes.get(p.name) != p.stat().st_size:
                    return False
        except OSError:
            return False
        return True

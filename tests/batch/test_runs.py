"""fastdet/batch/runs.py: a run's temporary folder, and those of runs whose process is gone."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from fastdet.batch.runs import remove_run, remove_stale_runs, run_id
from fastdet.batch.settings import Settings, output_paths
from fastdet.batch.task import PARTIAL_DIR, partial_path, run_dir


def test_stale_runs_removed_live_ones_kept(tmp_path: Path) -> None:
    """A run removes only its own temporary folder, and at start-up the folders of runs on
    this host whose process is gone -- never those of a run still going (another batch)."""
    s = Settings.create(video=True)
    host, _, _ = run_id().rpartition("-")[0].rpartition("-")
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    runs = {"mine": run_id(), "live": f"{host}-{os.getppid()}-0123abcd", "dead": f"{host}-{dead.pid}-0123abcd",
            "other-host": f"elsewhere-{dead.pid}-0123abcd"}
    for r in runs.values():
        for p in output_paths(tmp_path, "a", s).values():
            partial_path(run_dir(tmp_path, r), p, "0123456789abcdef").parent.mkdir(parents=True, exist_ok=True)
            partial_path(run_dir(tmp_path, r), p, "0123456789abcdef").write_bytes(b"x")
    assert remove_stale_runs(tmp_path) == [runs["dead"]]
    left = {p.name for p in (tmp_path / PARTIAL_DIR).iterdir()}
    assert left == {runs["mine"], runs["live"], runs["other-host"]}
    remove_run(tmp_path, runs["mine"])
    assert {p.name for p in (tmp_path / PARTIAL_DIR).iterdir()} == {runs["live"], runs["other-host"]}

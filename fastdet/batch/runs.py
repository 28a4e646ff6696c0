"""The temporary folders of batch runs (``OUT/.partial/HOST-PID-RANDOM``): this run's name,
removing it at the end, and removing those of runs on this host whose process is gone."""
from __future__ import annotations

import contextlib
import os
import re
import shutil
import socket
from pathlib import Path

from ..io.atomic import process_token
from .task import PARTIAL_DIR


def run_id() -> str:
    """``HOST-PID-RANDOM``: this batch run's temporary folder name (unique to the process)."""
    host = re.sub(r"[^A-Za-z0-9.]+", "_", socket.gethostname()) or "host"
    return f"{host}-{process_token()}"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove_run(out_dir: Path, run: str) -> None:
    """Remove run ``run``'s temporary folder, and ``.partial`` when it is then empty."""
    d = out_dir / PARTIAL_DIR
    shutil.rmtree(d / run, ignore_errors=True)
    with contextlib.suppress(OSError):
        d.rmdir()  # only when empty


def remove_stale_runs(out_dir: Path) -> list[str]:
    """Remove the temporary folders of batch runs on this host whose process is gone (a run
    killed outright); the folders of live runs and of other hosts stay. Returns the names."""
    d = out_dir / PARTIAL_DIR
    host = run_id().rsplit("-", 2)[0]
    gone: list[str] = []
    try:
        entries = list(d.iterdir())
    except OSError:
        return gone
    for p in entries:
        m = re.fullmatch(r"(?P<host>.+)-(?P<pid>\d+)-[0-9a-f]{8}", p.name)
        if p.is_dir() and m and m["host"] == host and not _pid_alive(int(m["pid"])):
            shutil.rmtree(p, ignore_errors=True)
            gone.append(p.name)
    return gone

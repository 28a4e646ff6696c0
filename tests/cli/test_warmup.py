"""``python -m fastdet warmup``: compiles every kernel signature the package lists (a cold
cache: tests/test_numba.py, slow); on a warm cache it loads them and says so, and
``--profile`` prints one line per signature."""
from __future__ import annotations

import subprocess
import sys

from fastdet import _numba
from tests.processes import finished

#: seconds a warmup run may take
TIMEOUT = 900


def _start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "fastdet", "warmup", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _run(*args: str) -> subprocess.CompletedProcess:
    return finished(_start(*args), TIMEOUT)


def test_warmup_then_profile():
    r = _run()  # compiles what this machine's cache lacks (nothing, usually), then loads everything
    assert r.returncode == 0, r.stderr
    n = len(_numba.tasks_of(_numba.all_kernels()))
    # the cache is complete now: the two runs that only load it run side by side
    again, profile = _start(), _start("--profile")
    r = finished(again, TIMEOUT)
    assert r.returncode == 0, r.stderr
    assert f"all {n} kernel signatures already compiled" in r.stderr, r.stderr
    r = finished(profile, TIMEOUT)
    assert r.returncode == 0, r.stderr
    lines = [x for x in r.stdout.splitlines()[1:] if x.strip()]
    assert len(lines) == n and all("[loaded from the cache]" in x for x in lines), r.stdout
    assert f"{n} kernel signatures in" in r.stderr


def test_warmup_whose_cache_cannot_be_written_fails_in_one_line(monkeypatch, capsys):
    """``warmup``'s job is the cache: when Numba could not write it (a full disk), the run says
    so in one line and exits 2 (issue 34, item 13: before, Numba's ENOSPC traceback); other
    commands note it and go on (tests/test_numba.py)."""
    from fastdet.cli.main import main

    monkeypatch.setattr(_numba, "ensure_compiled", lambda *a, **k: {})
    monkeypatch.setattr(_numba, "cache_failed", lambda: "No space left on device")
    assert main(["warmup"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "could not be stored in the Numba cache (No space left on device)" in err[0], err

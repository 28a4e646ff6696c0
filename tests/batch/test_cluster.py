"""fastdet/batch/cluster.py: the scheduler's address checked, a scheduler that never answers
given up, a stop signal during the wait; the Dask client's absence said in one line."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from fastdet.batch import cluster
from fastdet.batch.cluster import BatchInterrupted
from fastdet.errors import FastdetError


def test_scheduler_that_never_answers_is_given_up_and_a_stop_wakes_the_wait(tmp_path: Path) -> None:
    """An HTTP server where the scheduler should be: a Dask client's handshake waits there for
    ever. The connection is given up after its timeout, and a stop signal ends the wait."""
    from fastdet import signals
    from tests.media import http_server

    with http_server(tmp_path) as url:
        addr = "tcp://" + url.split("://", 1)[1]
        with pytest.raises(FastdetError, match="no answer in 1 s"):
            cluster._connect(addr, timeout=1)
        with signals.handled():
            threading_timer = __import__("threading").Timer(0.5, os.kill, (os.getpid(), signal.SIGTERM))
            threading_timer.start()
            t0 = time.monotonic()
            # a bound well above the signal's 0.5 s, and short: the helper thread left waiting
            # on the server's handshake (a daemon) ends with it, not minutes into later tests
            with signals.deferred(repeats=False, raise_on_exit=False), pytest.raises(BatchInterrupted) as stop:
                cluster._connect(addr, timeout=8)
            waited = time.monotonic() - t0
            threading_timer.join()
        assert stop.value.signum == signal.SIGTERM and waited < 6


def test_without_dask_says_how_to_get_it(tmp_path: Path) -> None:
    code = ("import sys; sys.modules['distributed'] = None\n"
            "from fastdet.cli.main import main\n"
            f"sys.exit(main(['batch', {str(tmp_path)!r}, '--out', {str(tmp_path / 'o')!r}]))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install fastdet[cluster]" in lines[0]
    assert not (tmp_path / "o").exists()


_NOT_DASK = """\
import socket, sys, threading
srv = socket.socket()
srv.bind(("127.0.0.1", 0))
srv.listen(8)
reply = bytes.fromhex(sys.argv[1])
def serve():
    held = []
    while True:
        c, _ = srv.accept()
        held.append(c)
        c.sendall(reply)
threading.Thread(target=serve, daemon=True).start()
from fastdet.cli.main import main
sys.exit(main(["batch", sys.argv[2], "--out", sys.argv[3], "--scheduler", "tcp://127.0.0.1:%d" % srv.getsockname()[1]]))
"""


@pytest.mark.parametrize("reply", [b"SSH-2.0-OpenSSH_8.9\r\n", b"\xff" * 64], ids=["banner", "bogus-length"])
def test_a_server_that_is_not_dask_is_one_line_at_once(tmp_path: Path, reply: bytes) -> None:
    """A server that answers, but not in Dask's protocol (a banner; a bogus frame length): before,
    "Unable to allocate 2.82 EiB ..." as the message, then 40 s more ignoring SIGINT and SIGTERM
    and a ``Client.__del__`` TimeoutError traceback (issue 34, item 9); now one line, the half-made
    client collected within its bound."""
    from tests.media import write_video

    clip = write_video(tmp_path / "c.mp4", 5)
    r = subprocess.run([sys.executable, "-c", _NOT_DASK, reply.hex(), str(clip), str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "does not speak Dask's protocol (is it a Dask scheduler?)" in lines[0], r.stderr
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").rglob("*"))  # nothing written


def test_dask_log_records_are_quiet_while_a_batch_runs() -> None:
    """A remote scheduler killed mid-run: Dask's client logged "distributed.client - ERROR -" with
    two tracebacks of its reconnect attempts (issue 34, item 19). Its loggers (Dask's config sets
    levels on the children too) are at CRITICAL while the client lives, and restored after."""
    import logging

    client_log = logging.getLogger("distributed.client")
    before = client_log.level
    client_log.setLevel(logging.WARNING)  # what Dask's default config sets
    try:
        with cluster._quiet_dask():
            assert not client_log.isEnabledFor(logging.ERROR)
            assert not logging.getLogger("distributed").isEnabledFor(logging.ERROR)
        assert client_log.level == logging.WARNING
    finally:
        client_log.setLevel(before)


def test_a_lost_scheduler_connection_is_said_in_words() -> None:
    from distributed.client import FutureCancelledError

    from fastdet.batch.job import _one_line

    exc = FutureCancelledError("fastdet-batch-x-v2", "scheduler-connection-lost")
    assert _one_line(exc) == "the connection to the Dask scheduler was lost (the video is run again on the next run)"

"""fastdet.exiting: a process with a thread left inside native code ends with the command's
status, its output flushed and its temporary files removed, without the interpreter's teardown
(which aborted: "terminate called without an active exception", exit 134)."""
from __future__ import annotations

import subprocess
import sys
import threading
import time

from fastdet import exiting


def test_threads_left_counts_only_live_threads():
    done = threading.Event()
    t = threading.Thread(target=done.wait, daemon=True)
    t.start()
    exiting.leave_behind(t)
    assert exiting.threads_left()
    done.set()
    t.join()
    assert not exiting.threads_left()


def test_exit_now_flushes_cleans_and_keeps_the_status(tmp_path):
    code = ("import sys, threading, time\n"
            "from pathlib import Path\n"
            "from fastdet import exiting\n"
            "from fastdet.io.atomic import partial_name\n"
            "partial_name(Path(sys.argv[1]) / 'o.mp4').write_text('half')\n"
            "t = threading.Thread(target=time.sleep, args=(60,), daemon=True); t.start()\n"
            "exiting.leave_behind(t)\n"
            "print('the result line', end='')\n"  # still buffered: stdout is a pipe
            "sys.stderr.write('fastdet video: error: one line\\n')\n"
            "exiting.exit_now(2)\n")
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert time.monotonic() - t0 < 30  # not the sleeping thread's 60 s
    assert p.returncode == 2 and p.stdout == "the result line" and p.stderr == "fastdet video: error: one line\n"
    assert list(tmp_path.iterdir()) == []

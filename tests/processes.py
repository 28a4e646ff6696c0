"""Child processes of the tests: :func:`finished` waits for one started with pipes."""
from __future__ import annotations

import subprocess


def finished(p: subprocess.Popen, timeout: float) -> subprocess.CompletedProcess:
    """``p`` (started with ``stdout`` and ``stderr`` pipes) waited for at most ``timeout`` s, as a
    :class:`subprocess.CompletedProcess`; a child still running when the wait ends (a timeout,
    a failure in between) is killed and reaped, so no test leaves one behind."""
    try:
        out, err = p.communicate(timeout=timeout)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)

"""Every way a process is told to stop (issue 14, item 3), with real signals sent to a real
``fastdet`` process (``subprocess`` + ``os.kill``).

SIGTERM and SIGHUP are handled like Ctrl-C: the frame being processed is finished, the
video closed, every output renamed to its final name, one line on stderr, exit status
128 + the signal. A process killed outright (SIGKILL) leaves only temporary names: never a
file under its final name that looks complete.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import pytest

from tests.media import fastdet_cmd, frames, leftovers, partials_of, write_video


@pytest.fixture(scope="module")
def long_clip(tmp_path_factory) -> Path:
    """Long enough (1500 frames) that no run ends before the signal reaches it."""
    return write_video(tmp_path_factory.mktemp("long") / "long.mp4", 1500, ("-c:v", "mpeg4", "-q:v", "8"))


def _start(clip: Path, out: Path, env: dict | None = None) -> tuple[subprocess.Popen, dict[str, Path]]:
    paths = {"video": out / "o.mp4", "boxes": out / "b.txt", "json": out / "b.jsonl"}
    p = subprocess.Popen(fastdet_cmd("video", clip, "-o", paths["video"], "--boxes", paths["boxes"],
                                     "--json", paths["json"], "--no-progress", "--no-oncoming"),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env={**os.environ, **(env or {})})
    return p, paths


def _wait_for_frames(p: subprocess.Popen, js: Path, n: int = 3) -> None:
    """Until the run has written ``n`` frames to its (temporary) JSON-lines file."""
    while True:
        assert p.poll() is None, p.communicate()
        tmps = partials_of(js)  # the run's own temporary name (its pid and token)
        if tmps and tmps[0].read_text().count("\n") >= n:
            return
        time.sleep(0.05)


def _frames_in_video(path: Path) -> int:
    cap = cv2.VideoCapture(str(path))
    n = 0
    while cap.read()[0]:
        n += 1
    return n


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_stop_signal_finishes_the_frame_and_renames(long_clip, tmp_path, sig):
    p, paths = _start(long_clip, tmp_path)
    _wait_for_frames(p, paths["json"])
    os.kill(p.pid, sig)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 128 + sig, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and f"interrupted ({signal.Signals(sig).name})" in lines[0], err
    assert "Traceback" not in err and out == ""
    assert leftovers(tmp_path) == []
    frames = [json.loads(ln)["frame"] for ln in paths["json"].read_text().splitlines()]
    n = len(frames)
    assert 3 <= n < 1500 and frames == list(range(1, n + 1))
    assert _frames_in_video(paths["video"]) == n  # playable, the same frames as the box files
    assert f"{n} frames in" in lines[0]


def test_sigkill_leaves_only_temporary_names(long_clip, tmp_path):
    p, paths = _start(long_clip, tmp_path)
    _wait_for_frames(p, paths["json"])
    p.kill()
    p.communicate(timeout=60)
    assert not any(path.exists() for path in paths.values())  # nothing looks complete
    left = set(leftovers(tmp_path))
    assert len(partials_of(paths["json"])) == 1 and len(partials_of(paths["boxes"])) == 1
    assert left >= {partials_of(paths["json"])[0].name, partials_of(paths["boxes"])[0].name}
    assert all(f".{p.pid}-" in name for name in left)  # named after the process that wrote them


def test_ctrl_c_while_compiling_is_one_line_exit_130(tmp_path):
    """A first run (an empty Numba cache) announces the compilation; Ctrl-C during it ends the
    command with one line and exit 130, not a traceback from inside the compiler."""
    img = tmp_path / "in.jpg"
    cv2.imwrite(str(img), next(frames(1, 640, 360)))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    p = subprocess.Popen(fastdet_cmd("image", img, "-o", tmp_path / "out.jpg"), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=env)
    assert p.stderr is not None
    first = p.stderr.readline()  # the compile notice comes before the compiling
    assert "compiling" in first, first
    os.kill(p.pid, signal.SIGINT)
    _, rest = p.communicate(timeout=300)
    assert p.returncode == 130, first + rest
    lines = rest.strip().splitlines()
    assert len(lines) == 1 and "interrupted (SIGINT)" in lines[0], rest
    assert not (tmp_path / "out.jpg").exists() and leftovers(tmp_path) == []


@pytest.fixture(scope="module")
def python_start() -> float:
    """Seconds the interpreter itself takes to start here (site packages included): a signal
    before that reaches Python's own start-up, not fastdet."""
    t0 = time.monotonic()
    subprocess.run([sys.executable, "-c", "pass"], check=True)
    return time.monotonic() - t0


@pytest.mark.parametrize("after", [0.1, 0.3, 0.6])
@pytest.mark.parametrize("command", ["video", "train"])
def test_stop_while_starting_is_one_line(tmp_path, command, after, python_start):
    """A signal while the command's modules are still being imported (before the dispatcher's
    handlers): one line and 128 + the signal, never a KeyboardInterrupt traceback."""
    args = ([str(tmp_path / "missing.mp4"), "--boxes", str(tmp_path / "b.txt")] if command == "video"
            else ["--out", str(tmp_path / "m.npz"), "--data", str(tmp_path)])
    p = subprocess.Popen(fastdet_cmd(command, *args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(python_start + after)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    # the run was stopped, or had already ended with its own one-line error
    assert (p.returncode == 130 and "interrupted (SIGINT)" in err) or p.returncode == 2, (p.returncode, err)
    assert len(err.strip().splitlines()) == 1, err


def test_stop_after_the_command_ended_keeps_its_status():
    """A stop signal once the command has returned (while the interpreter shuts down) cannot
    turn its exit status into a kill or a second line."""
    code = ("import os, signal, sys\n"
            "import fastdet.cli.main\n"
            "sys.modules['fastdet.cli.main'].main = lambda: 2\n"
            "from fastdet.__main__ import run\n"
            "status = run()\n"
            "os.kill(os.getpid(), signal.SIGINT)\n"
            "os.kill(os.getpid(), signal.SIGTERM)\n"
            "sys.exit(status)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 2 and p.stderr == "", (p.returncode, p.stderr)

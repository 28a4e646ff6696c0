"""Real media files for the robustness tests, made with a real muxer (the FFmpeg binary of
imageio-ffmpeg, PyAV for packet positions) -- not only files cut with ``head -c``."""
from __future__ import annotations

import functools
import http.server
import os
import resource
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import av
import cv2
import imageio_ffmpeg
import numpy as np

FFMPEG = imageio_ffmpeg.get_ffmpeg_exe()
#: an intra-only MPEG-4 clip: every packet one frame, damage stays local
INTRA = ("-c:v", "mpeg4", "-q:v", "4", "-g", "1")
#: MPEG-4 with a keyframe every 12 frames: an ``-ss ... -c copy`` cut gets an edit list
GOP12 = ("-c:v", "mpeg4", "-q:v", "4", "-g", "12")


def frames(n: int, w: int = 320, h: int = 240, grey: bool = False) -> Iterator[np.ndarray]:
    """``n`` BGR frames: a blocky random colour background and a red box moving right.

    The background is 16 px blocks of values 64-191: with 8 px blocks of 0-254 the detector
    fired on 300-700 windows of every decoded frame (the codec's ringing at the blocks'
    edges), about 30 with these, and the neighbour split's mean shift over a blob's windows
    (quadratic in their number) made a run on such a clip about ten times slower."""
    rng = np.random.default_rng(0)
    bg = rng.integers(64, 192, (h // 16 + 1, w // 16 + 1, 3), dtype=np.uint8)
    bg = np.ascontiguousarray(np.repeat(np.repeat(bg, 16, 0), 16, 1)[:h, :w])
    for i in range(n):
        f = bg.copy()
        x = (i * 5) % max(w - 60, 1)
        f[h // 3: h // 3 + 50, x: x + 60] = (0, 0, 255)
        if grey:
            f[:] = f.mean(axis=2, keepdims=True).astype(np.uint8)
        yield f


def write_video(path: Path, n: int, codec: Sequence[str] = INTRA, w: int = 320, h: int = 240,
                fps: int = 25, grey: bool = False, extra: Sequence[str] = ()) -> Path:
    """Encode :func:`frames` with the FFmpeg binary (raw BGR frames on its stdin)."""
    p = subprocess.Popen([FFMPEG, "-v", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24", "-s", f"{w}x{h}",
                          "-r", str(fps), "-i", "-", *codec, *extra, str(path)], stdin=subprocess.PIPE)
    assert p.stdin is not None
    for f in frames(n, w, h, grey):
        p.stdin.write(f.tobytes())
    p.stdin.close()
    assert p.wait() == 0
    return path


def cut(src: Path, dst: Path, start: int, n: int) -> Path:
    """Frames ``start .. start + n - 1`` of ``src`` re-encoded (mp4v) into ``dst``."""
    cap = cv2.VideoCapture(str(src))
    for _ in range(start):
        assert cap.grab()
    ok, frame = cap.read()
    assert ok
    h, w = frame.shape[:2]
    out = cv2.VideoWriter(str(dst), cv2.VideoWriter_fourcc(*"mp4v"), 25, (w, h))
    assert out.isOpened()
    k = 0
    while ok and k < n:
        out.write(frame)
        k += 1
        ok, frame = cap.read()
    out.release()
    cap.release()
    assert k == n
    return dst


def ffmpeg(*args: str) -> None:
    subprocess.run([FFMPEG, "-v", "error", "-y", *args], check=True)


def cut_copy(src: Path, dst: Path, ss: float = 0.7) -> Path:
    """``ffmpeg -ss SS -i SRC -c copy DST``: the header counts more frames than decode."""
    ffmpeg("-ss", str(ss), "-i", str(src), "-c", "copy", str(dst))
    return dst


def packets(path: Path) -> list[tuple[int, int]]:
    """``(file offset, size)`` of each video packet, in stream order (PyAV)."""
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        return [(p.pos, p.size) for p in c.demux(s) if p.size]


def damage(src: Path, dst: Path, frames_0based: Sequence[int]) -> Path:
    """A copy of ``src`` with the payload of the given frames' packets zeroed."""
    data = bytearray(src.read_bytes())
    pk = packets(src)
    for k in frames_0based:
        pos, size = pk[k]
        data[pos + 8: pos + size] = bytes(size - 8)
    dst.write_bytes(bytes(data))
    return dst


def decoded_count(path: Path) -> int:
    """Frames OpenCV decodes from ``path``."""
    cap = cv2.VideoCapture(str(path))
    n = 0
    while cap.read()[0]:
        n += 1
    cap.release()
    return n


def header_count(path: Path) -> int:
    cap = cv2.VideoCapture(str(path))
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    cap.release()
    return n


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@contextmanager
def http_server(folder: Path) -> Iterator[str]:
    """Serve ``folder`` over HTTP on 127.0.0.1 (a free port); yields the base URL."""
    handler = functools.partial(_Quiet, directory=str(folder))
    srv = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    try:
        yield f"http://127.0.0.1:{srv.server_address[1]}"
    finally:
        srv.shutdown()
        srv.server_close()


def fastdet_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "fastdet", *map(str, args)]


def run_limited(cmd: Sequence[str], max_bytes: int, **kw) -> subprocess.CompletedProcess:
    """Run ``cmd`` with ``RLIMIT_FSIZE`` = ``max_bytes`` ("disk full" for files it writes;
    Python ignores SIGXFSZ, so a write past the limit fails with EFBIG)."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    env = {**os.environ, **kw.pop("env", {})}
    return subprocess.run(list(cmd), preexec_fn=limit, capture_output=True, text=True, env=env, check=False,
                          timeout=kw.pop("timeout", 300), **kw)


def partials_of(path: Path) -> list[Path]:
    """The temporary files of the output ``path`` that any process is writing or left
    (``.NAME.partial.PID-TOKEN.EXT``, :func:`fastdet.io.atomic.partial_name`)."""
    return sorted(path.parent.glob(f".{path.stem}.partial.*{path.suffix}"))


def leftovers(folder: Path) -> list[str]:
    """Temporary (``.partial``) files left in ``folder``."""
    return sorted(p.name for p in folder.iterdir() if ".partial" in p.name)

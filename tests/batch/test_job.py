"""fastdet/batch/job.py: whole ``python -m fastdet batch`` runs on a LocalCluster of 2 workers
and on a real ``dask scheduler`` + ``dask worker`` cluster, on short clips cut from the
annotated clips in the test (plus a broken file). The modules it runs have their own test
modules beside this one (inputs, manifest, progress, runs, task, cluster, ...)."""
from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import pytest

pytest.importorskip("distributed")
pyarrow = pytest.importorskip("pyarrow")
import pyarrow.parquet as pq

from fastdet.batch.job import remove_run
from fastdet.batch.settings import Settings
from fastdet.batch.task import PARTIAL_DIR, VideoTask, commit_outputs, run_video
from fastdet.cli.main import main
from fastdet.io.atomic import process_token
from fastdet.io.motfiles import read_predictions
from tests import processes
from tests.media import cut

FASTDET = [sys.executable, "-m", "fastdet"]
TIMEOUT = 240


def batch(*args: str | Path, timeout: float = TIMEOUT, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(FASTDET + ["batch", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env)


def batch_started(*args: str | Path) -> subprocess.Popen:
    """``fastdet batch`` started, not waited for (:func:`finished`)."""
    return subprocess.Popen(FASTDET + ["batch", *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def finished(p: subprocess.Popen, timeout: float = TIMEOUT) -> subprocess.CompletedProcess:
    return processes.finished(p, timeout)


def manifest_lines(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines() if line.strip()]


def partials(out: Path) -> list[Path]:
    """Every file and folder under ``OUT/.partial`` (the temporary files of all runs)."""
    d = out / PARTIAL_DIR
    return sorted(d.rglob("*")) if d.is_dir() else []


def run_and_commit(task: VideoTask) -> dict:
    """A task run here, its outputs given their final names as the batch's main process does."""
    summary = run_video(task)
    if summary["status"] == "done":
        commit_outputs(summary, task.out_dir)
        remove_run(Path(task.out_dir), task.run or process_token())
    return summary


# ------------------------------------------------------------------------------------------
# whole runs


@pytest.fixture(scope="module")
def clips(tmp_path_factory: pytest.TempPathFactory, data: Path) -> Path:
    """A folder: two 6-frame clips cut from the annotated clips (one in a subfolder) and a
    file that is not a video."""
    d = tmp_path_factory.mktemp("clips")
    (d / "day2").mkdir()
    cut(data / "videos" / "test_video.mp4", d / "road.mp4", 10, 6)
    cut(data / "videos" / "test_small1.mp4", d / "day2" / "oncoming.mp4", 30, 6)
    (d / "broken.mp4").write_bytes(b"this is not a video\n" * 100)
    return d


@pytest.fixture(scope="module")
def first_run_started(clips: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, subprocess.Popen]]:
    """The first batch, started (:func:`first_run` waits for it)."""
    out = tmp_path_factory.mktemp("out")
    p = batch_started(clips, "--out", out, "--workers", "2", "--json", "--video", "--table", out / "boxes.parquet",
                      "--no-progress")
    yield out, p
    if p.poll() is None:
        p.kill()
        p.wait()


@pytest.fixture(scope="module")
def first_run(first_run_started) -> tuple[Path, subprocess.CompletedProcess]:
    out, p = first_run_started
    return out, finished(p)


def test_batch_boxes_identical_to_video(clips: Path, first_run_started, tmp_path: Path, request) -> None:
    """The batch's outputs equal ``fastdet video``'s (run in this process: the command is the
    same, a fresh interpreter for each clip only cost its start-up; meanwhile the batch runs)."""
    for name, clip in (("road", clips / "road.mp4"), ("oncoming", clips / "day2" / "oncoming.mp4")):
        assert main(["video", str(clip), "--boxes", str(tmp_path / f"{name}.txt"),
                     "--json", str(tmp_path / f"{name}.jsonl"), "--no-progress"]) == 0
    out, _ = request.getfixturevalue("first_run")
    for name in ("road", "oncoming"):
        assert (out / f"{name}.boxes.txt").read_bytes() == (tmp_path / f"{name}.txt").read_bytes()
        assert (out / f"{name}.boxes.jsonl").read_bytes() == (tmp_path / f"{name}.jsonl").read_bytes()
        assert (tmp_path / f"{name}.txt").stat().st_size > 0  # the clips have cars in them
        cap = cv2.VideoCapture(str(out / f"{name}.annotated.mp4"))
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 6
        cap.release()


def test_batch_reports_the_broken_file_and_exits_1(first_run) -> None:
    out, r = first_run
    assert r.returncode == 1, r.stderr
    assert "broken.mp4" in r.stdout and "not a video" in r.stdout
    assert "Traceback" not in r.stderr
    done = next(line for line in r.stdout.splitlines() if line.startswith("done"))
    failed = next(line for line in r.stdout.splitlines() if line.startswith("failed "))
    assert done.split()[1:3] == ["2", "12"] and failed.split()[1] == "1"
    assert not (out / "broken.boxes.txt").exists() and not partials(out)


def test_batch_manifest(first_run, clips: Path) -> None:
    out, _ = first_run
    entries = {e["name"]: e for e in manifest_lines(out)}
    assert set(entries) == {"road", "oncoming", "broken"}
    for name in ("road", "oncoming"):
        e = entries[name]
        assert e["status"] == "done" and e["frames"] == 6
        assert e["outputs"] == {"boxes": f"{name}.boxes.txt", "json": f"{name}.boxes.jsonl",
                                "video": f"{name}.annotated.mp4"}
        assert e["sizes"] == {f: (out / f).stat().st_size for f in e["outputs"].values()}
        assert e["boxes"] == len(read_predictions(out / f"{name}.boxes.txt"))
        assert e["settings"]["outputs"] == ["boxes", "json", "video"]
    assert entries["road"]["input"] == str(clips / "road.mp4")
    assert entries["broken"]["status"] == "failed" and "not a video" in entries["broken"]["error"]
    assert entries["broken"]["permanent"] is True
    assert "\n" not in entries["broken"]["error"]


def test_batch_table(first_run) -> None:
    out, _ = first_run
    t = pq.read_table(out / "boxes.parquet").to_pylist()
    want = []
    for name in ("oncoming", "road"):  # the folder's order: day2/oncoming.mp4 before road.mp4
        p = read_predictions(out / f"{name}.boxes.txt")
        want += [(name, int(f), int(i), *map(float, b)) for f, i, b in zip(p.frames, p.ids, p.boxes)]
    assert [(r["video"], r["frame"], r["id"], r["x1"], r["y1"], r["x2"], r["y2"]) for r in t] == want


def test_batch_rerun_skips_then_overwrite_redoes(first_run, clips: Path) -> None:
    out, _ = first_run
    before = {f.name: f.stat().st_ino for f in out.glob("*.boxes.txt")}
    n_lines = len(manifest_lines(out))
    r = batch(clips, "--out", out, "--workers", "2", "--json", "--video", "--no-progress")
    # the broken file is not run again (unchanged, failed because of what it is), but still failed
    assert r.returncode == 1, r.stderr
    skipped = next(line for line in r.stdout.splitlines() if line.startswith("skipped"))
    assert skipped.split()[1:3] == ["2", "12"]
    assert "broken.mp4" in r.stdout and "--overwrite tries again" in r.stdout
    assert {f.name: f.stat().st_ino for f in out.glob("*.boxes.txt")} == before
    lines = manifest_lines(out)
    assert len(lines) == n_lines
    # other settings (no tracker, no --video): nothing is complete for them, so all is redone,
    # as `video --no-track` does it; and the broken file, changed since, is tried again
    broken = clips / "broken.mp4"
    st = broken.stat()
    os.utime(broken, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    # (one worker from here on: what is run again does not depend on how many there are, and
    # a second worker process only costs its start-up)
    b = batch_started(clips, "--out", out, "--workers", "1", "--json", "--no-track", "--no-progress")
    try:  # (what it is compared with, computed here meanwhile)
        ref = out.parent / "road_no_track.txt"
        assert main(["video", str(clips / "road.mp4"), "--no-track", "--boxes", str(ref), "--no-progress"]) == 0
    finally:
        r = finished(b)
    assert r.returncode == 1, r.stderr
    lines = manifest_lines(out)
    assert sorted(e["name"] for e in lines[n_lines:]) == ["broken", "oncoming", "road"]
    last = {e["name"]: e for e in lines[n_lines:]}["road"]
    assert last["settings"]["outputs"] == ["boxes", "json"] and last["settings"]["tracker"] is None
    assert (out / "road.boxes.txt").read_bytes() == ref.read_bytes()
    assert set(read_predictions(ref).ids.tolist()) == {-1}

    # --overwrite: the same settings as the first run, but everything is done again
    before = {f.name: f.stat().st_ino for f in out.glob("*.boxes.*")}
    r = batch(clips, "--out", out, "--workers", "1", "--overwrite", "--json", "--video", "--no-progress")
    assert r.returncode == 1, r.stderr
    redone = {e["name"]: e for e in manifest_lines(out)[len(lines):]}
    assert set(redone) == {"road", "oncoming", "broken"}
    assert all(f.stat().st_ino != before[f.name] for f in out.glob("*.boxes.*"))
    assert (out / "road.boxes.txt").read_bytes() != ref.read_bytes()  # with track ids again


# ------------------------------------------------------------------------------------------
# a killed worker, a killed batch


@pytest.fixture(scope="module")
def long_clips(tmp_path_factory: pytest.TempPathFactory, data: Path) -> tuple[Path, dict[str, bytes]]:
    """Five 15-frame clips and the boxes file of each (run in this process, as a task). A task
    takes a second or two: long enough to be seen running, killed or stopped mid-way."""
    d = tmp_path_factory.mktemp("long")
    src = data / "videos" / "test_small1.mp4"
    for k in range(5):
        cut(src, d / f"c{k}.mp4", 10 * k, 15)
    ref = tmp_path_factory.mktemp("ref")
    s = Settings.create()
    want = {}
    for k in range(5):
        summary = run_and_commit(VideoTask(str(d / f"c{k}.mp4"), f"c{k}", str(ref), s))
        assert summary["status"] == "done", summary
        want[f"c{k}"] = (ref / f"c{k}.boxes.txt").read_bytes()
    return d, want


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(cond, timeout: float, what: str, step: float = 0.05):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = cond()
        if v:
            return v
        time.sleep(step)
    raise AssertionError(f"timed out waiting for {what}")


@pytest.mark.slow
def test_real_cluster_worker_killed_mid_task_nothing_lost(long_clips, tmp_path: Path) -> None:
    clips, want = long_clips
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    procs: list[subprocess.Popen] = []
    log = open(tmp_path / "dask.log", "w")
    try:
        procs.append(subprocess.Popen(["dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                       "--no-dashboard"], stdout=log, stderr=log, env=env))
        workers = [subprocess.Popen(["dask", "worker", addr, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                                     "--host", "127.0.0.1", "--name", f"w{k}"], stdout=log, stderr=log, env=env)
                   for k in range(2)]
        procs += workers
        out = tmp_path / "out"
        b = subprocess.Popen(FASTDET + ["batch", str(clips), "--out", str(out), "--scheduler", addr, "--no-progress"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        procs.append(b)
        # both workers busy (two videos being written), then one of them dies
        def two_running() -> list[Path] | None:
            boxes = [p for p in partials(out) if ".boxes." in p.name]
            return boxes if len(boxes) >= 2 else None

        running = wait_for(two_running, 120, "two running tasks")
        # temporary names are TOKEN.KIND.EXT (short whatever the video's name): the attempts' tokens
        in_progress = {m["token"] for m in (re.match(r"^\.?(?P<token>[0-9a-f]{16})\.boxes\.", p.name) for p in running)
                       if m}
        assert len(in_progress) >= 2, running
        workers[0].send_signal(signal.SIGKILL)
        workers[0].wait(timeout=30)
        _, stderr = b.communicate(timeout=TIMEOUT)
        assert b.returncode == 0, stderr
        entries = {e["name"]: e for e in manifest_lines(out)}
        assert {n: e["status"] for n, e in entries.items()} == {n: "done" for n in want}
        for name, content in want.items():
            assert (out / f"{name}.boxes.txt").read_bytes() == content, name
        # the killed worker's video was run again: its final attempt is not the one seen running
        assert not in_progress <= {e["token"] for e in entries.values()}
        assert not partials(out)
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
        log.close()


@pytest.mark.slow
def test_sigterm_leaves_no_incomplete_output_and_a_rerun_finishes(long_clips, tmp_path: Path) -> None:
    clips, want = long_clips
    out = tmp_path / "out"
    b = subprocess.Popen(FASTDET + ["batch", str(clips), "--out", str(out), "--workers", "2", "--no-progress"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        def one_done() -> bool:
            try:  # (a line may be half-written while we read)
                return any(e["status"] == "done" for e in manifest_lines(out))
            except (OSError, json.JSONDecodeError):
                return False

        wait_for(one_done, 120, "a finished video")
        b.send_signal(signal.SIGTERM)
        _, stderr = b.communicate(timeout=60)
    finally:
        if b.poll() is None:
            b.kill()
    assert b.returncode == 128 + signal.SIGTERM, stderr
    last = stderr.strip().splitlines()[-1]
    assert "SIGTERM" in last and "Traceback" not in stderr
    done_before = {e["name"] for e in manifest_lines(out) if e["status"] == "done"}
    assert done_before and len(done_before) < len(want)
    # the truth: as many done as the manifest says, the rest stopped
    m = re.search(r"(\d+) video\(s\) done in this run, (\d+) stopped", last)
    assert m and int(m[1]) == len(done_before) and int(m[2]) == len(want) - len(done_before), last
    # whatever has a final name is complete and has its manifest line (none got one after
    # the signal); nothing half-written is left behind
    for f in out.glob("*.boxes.txt"):
        assert f.read_bytes() == want[f.name.split(".")[0]], f.name
    assert {f.name.split(".")[0] for f in out.glob("*.boxes.txt")} == done_before
    assert not partials(out)

    r = batch(clips, "--out", out, "--workers", "2", "--no-progress")
    assert r.returncode == 0, r.stderr
    skipped = next(line for line in r.stdout.splitlines() if line.startswith("skipped"))
    assert int(skipped.split()[1]) == len(done_before)
    for name, content in want.items():
        assert (out / f"{name}.boxes.txt").read_bytes() == content, name


class _NotDask:
    """A server that answers every connection with an SSH banner (not Dask's protocol)."""

    def __enter__(self) -> str:
        import threading

        self.srv = socket.socket()
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(8)
        self.held: list[socket.socket] = []

        def serve() -> None:
            while True:
                try:
                    c, _ = self.srv.accept()
                except OSError:
                    return
                self.held.append(c)
                c.sendall(b"SSH-2.0-OpenSSH_8.9\r\n")

        threading.Thread(target=serve, daemon=True).start()
        return f"tcp://127.0.0.1:{self.srv.getsockname()[1]}"

    def __exit__(self, *exc: object) -> None:
        self.srv.close()
        for c in self.held:
            c.close()


def test_a_failed_start_leaves_no_out_folder_it_made(tmp_path: Path) -> None:
    """``batch --scheduler`` to a server that is not Dask (or a refused ``--table``): one line,
    exit 2, and no ``--out`` folder (nor a parent) left that the run made (issue 34: an empty
    ``--out`` was left behind); an ``--out`` that existed stays."""
    from tests.media import write_video

    clip = write_video(tmp_path / "c.mp4", 3)
    (tmp_path / "kept").mkdir()
    procs: list[subprocess.Popen] = []
    try:
        with _NotDask() as addr:
            # the three runs are independent (each its own --out): side by side, each its own process
            procs += [batch_started(*args) for args in (
                (clip, "--out", tmp_path / "new" / "o", "--scheduler", addr, "--no-progress"),
                (clip, "--out", tmp_path / "kept", "--scheduler", addr, "--no-progress"),
                (clip, "--out", tmp_path / "o2", "--table", tmp_path / "o2" / "missing" / "t.csv"))]
            new, kept, table = procs
            r = finished(new)
            assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
            assert "cannot connect to the Dask scheduler" in r.stderr, r.stderr
            assert not (tmp_path / "new").exists()
            r = finished(kept)
            assert r.returncode == 2, r.stderr
            assert (tmp_path / "kept").is_dir() and list((tmp_path / "kept").iterdir()) == []
        r = finished(table)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not (tmp_path / "o2").exists()
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.mp4", "kept"]

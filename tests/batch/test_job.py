"""``python -m fastdet batch``: inputs, manifest, and whole runs on a LocalCluster of 2
workers and on a real ``dask scheduler`` + ``dask worker`` cluster, on short clips cut from
the annotated clips in the test (plus a broken file)."""
from __future__ import annotations

import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import cv2
import pytest

pytest.importorskip("distributed")
pyarrow = pytest.importorskip("pyarrow")
import pyarrow.parquet as pq

from fastdet.batch import job
from fastdet.batch.inputs import batch_writes, expand_inputs, output_names
from fastdet.batch.job import BatchInterrupted, remove_run, remove_stale_runs, run_id
from fastdet.batch.manifest import Manifest, input_stat
from fastdet.batch.progress import BatchProgress
from fastdet.batch.settings import MANIFEST_NAME, SUFFIXES, Settings, output_paths
from fastdet.batch.task import PARTIAL_DIR, VideoTask, commit_outputs, partial_path, run_dir, run_video
from fastdet.cli.main import main
from fastdet.errors import DataError, FastdetError, WriteError
from fastdet.io.atomic import process_token
from fastdet.io.motfiles import read_predictions

FASTDET = [sys.executable, "-m", "fastdet"]
TIMEOUT = 240


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


def batch(*args: str | Path, timeout: float = TIMEOUT, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(FASTDET + ["batch", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env)


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
# inputs, names, manifest: no cluster


def test_inputs_folders_globs_lists_in_order_each_once(tmp_path: Path) -> None:
    (tmp_path / "d" / "sub").mkdir(parents=True)
    (tmp_path / "d" / ".hidden").mkdir()
    for rel in ("d/b.mp4", "d/a.MP4", "d/sub/c.avi", "d/notes.txt.bak", "d/.x.mp4", "d/.hidden/h.mp4", "e.mkv"):
        (tmp_path / rel).write_bytes(b"x")
    lst = tmp_path / "list.txt"
    lst.write_text("# clips\n\ne.mkv\nd/b.mp4\n")
    got = expand_inputs([str(tmp_path / "d"), str(tmp_path / "*.mkv"), str(lst)])
    rel = [p.relative_to(tmp_path).as_posix() for p in got]
    assert rel == ["d/a.MP4", "d/b.mp4", "d/sub/c.avi", "e.mkv"]
    assert all(p.is_absolute() for p in got)
    with pytest.raises(DataError, match="file not found"):
        expand_inputs([str(tmp_path / "nope.mp4")])
    with pytest.raises(DataError, match="matches no video"):
        expand_inputs([str(tmp_path / "*.mov")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataError, match="no video found"):
        expand_inputs([str(tmp_path / "empty")])


def test_output_names_unique_and_stable() -> None:
    vids = [Path("/x/day1/clip.mp4"), Path("/x/day2/clip.mp4"), Path("/y/clip.avi"), Path("/y/clip.mp4"),
            Path("/z/other clip.mp4")]
    names = output_names(vids)
    assert names[4] == "other_clip"
    assert len({n.lower() for n in names}) == len(names)
    assert names[:2] == ["day1_clip", "day2_clip"]
    # a name depends on the videos, not on their order
    assert output_names(vids[::-1]) == names[::-1]


def test_manifest_resume_rules_and_a_cut_short_line(tmp_path: Path) -> None:
    video = tmp_path / "v.mp4"
    video.write_bytes(b"0123")
    box = tmp_path / "v.boxes.txt"
    box.write_text("1,-1,1,2,3,4,0.5,-1,-1,-1\n")
    m = Manifest(tmp_path / "manifest.jsonl")
    entry = {"input": str(video), "name": "v", "status": "done", "settings_hash": "h",
             "outputs": {"boxes": box.name}, "sizes": {box.name: box.stat().st_size}, **input_stat(video)}
    m.append(entry)
    outs = {"boxes": box}
    assert Manifest(m.path).is_complete(video, "v", "h", outs)
    assert not Manifest(m.path).is_complete(video, "v", "other settings", outs)
    assert not Manifest(m.path).is_complete(video, "w", "h", outs)
    assert not Manifest(m.path).is_complete(video, "v", "h", {**outs, "json": tmp_path / "v.boxes.jsonl"})
    box.write_text("1,-1,1,2,3,4,0.5,-1,-1,-1\n2,-1,1,2,3,4,0.5,-1,-1,-1\n")  # changed size
    assert not Manifest(m.path).is_complete(video, "v", "h", outs)
    # a crash mid-line: the line is ignored and the file rewritten without it
    with open(m.path, "a") as fh:
        fh.write('{"input": "/b.mp4", "sta')
    m2 = Manifest(m.path)
    assert list(m2.entries) == [str(video)]
    assert m.path.read_text().endswith("\n") and len(manifest_lines(tmp_path)) == 1


def test_progress_counts_a_retried_attempt_once() -> None:
    p = BatchProgress(["a", "b"], enabled=False)
    p.on_event((0.0, {"name": "a", "token": "t1", "frames": 5, "expected": 10}))
    p.on_event((0.0, {"name": "a", "token": "t2", "frames": 2, "expected": 10}))  # the retry
    p.on_event((0.0, {"name": "b", "token": "t3", "frames": 4, "expected": 8}))
    p.on_event((0.0, "garbage"))
    assert sum(f for _, f in p._frames.values()) == 6
    p.close()


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


def test_batch_never_reads_what_it_writes(tmp_path: Path) -> None:
    d = tmp_path / "d"
    d.mkdir()
    for n in ("a.mp4", "a.annotated.mp4", "b.mov"):
        (d / n).write_bytes(b"v")
    writes = batch_writes(d, SUFFIXES.values(), [d / MANIFEST_NAME])
    # a folder (or glob) holding the batch's own outputs: they are left out
    assert [p.name for p in expand_inputs([str(d)], writes)] == ["a.mp4", "b.mov"]
    assert [p.name for p in expand_inputs([str(d / "*.mp4")], writes)] == ["a.mp4"]
    # named as an input (directly, through a symlink, in a list file): refused in one line
    (tmp_path / "link.mp4").symlink_to(d / "a.annotated.mp4")
    (tmp_path / "list.txt").write_text(f"{d / 'a.mp4'}\n{d / 'a.annotated.mp4'}\n")
    for arg in (d / "a.annotated.mp4", tmp_path / "link.mp4", tmp_path / "list.txt"):
        with pytest.raises(DataError, match="is a file this batch writes"):
            expand_inputs([str(d / "a.mp4"), str(arg)], writes)
    # the same folder as input with the output folder elsewhere: every video is an input
    assert len(expand_inputs([str(d)], batch_writes(tmp_path / "o", SUFFIXES.values()))) == 3


def test_cli_refuses_an_output_as_input_before_any_work(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    d = tmp_path / "d"
    d.mkdir()
    (d / "a.mp4").write_bytes(b"v")
    (d / "a.annotated.mp4").write_bytes(b"keep")
    assert main(["batch", str(d / "a.mp4"), str(d / "a.annotated.mp4"), "--out", str(d), "--video"]) == 2
    assert "a.annotated.mp4: is a file this batch writes" in capsys.readouterr().err
    assert (d / "a.annotated.mp4").read_bytes() == b"keep" and sorted(p.name for p in d.iterdir()) == [
        "a.annotated.mp4", "a.mp4"]


@pytest.mark.parametrize("address", ["not a url", "tcp://", "tcp://host-without-port", "http//x:1"])
def test_scheduler_address_that_is_not_one(tmp_path: Path, capsys: pytest.CaptureFixture, address: str) -> None:
    (tmp_path / "a.mp4").write_bytes(b"v")
    assert main(["batch", str(tmp_path / "a.mp4"), "--out", str(tmp_path / "o"), "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "is not a scheduler address" in err
    assert not (tmp_path / "o").exists()


def test_scheduler_that_never_answers_is_given_up_and_a_stop_wakes_the_wait(tmp_path: Path) -> None:
    """An HTTP server where the scheduler should be: a Dask client's handshake waits there for
    ever. The connection is given up after its timeout, and a stop signal ends the wait."""
    from fastdet import signals
    from tests.media import http_server

    with http_server(tmp_path) as url:
        addr = "tcp://" + url.split("://", 1)[1]
        with pytest.raises(FastdetError, match="no answer in 1 s"):
            job._connect(addr, timeout=1)
        with signals.handled():
            threading_timer = __import__("threading").Timer(0.5, os.kill, (os.getpid(), signal.SIGTERM))
            threading_timer.start()
            with signals.deferred(repeats=False, raise_on_exit=False), pytest.raises(BatchInterrupted) as stop:
                job._connect(addr, timeout=120)
            threading_timer.join()
        assert stop.value.signum == signal.SIGTERM


def test_a_failed_write_is_not_a_property_of_the_video(tmp_path: Path, data: Path, monkeypatch) -> None:
    """A full disk (a write that fails), a temporary file that vanished: recorded as failed
    but not ``permanent``, so the next run tries the video again."""
    clip = cut(data / "videos" / "test_small1.mp4", tmp_path / "c.mp4", 0, 3)
    s = Settings.create()
    from fastdet.io.motfiles import MotWriter

    def full(self, *a, **kw):
        raise WriteError(f"{self.name}: cannot write (No space left on device)")

    with monkeypatch.context() as m:
        m.setattr(MotWriter, "write_detections", full)
        summary = run_video(VideoTask(str(clip), "c", str(tmp_path / "o1"), s, None, "r1"))
    assert summary["status"] == "failed" and summary["permanent"] is False and "No space" in summary["error"]
    # a done task whose temporary file vanished before the batch renamed it
    (tmp_path / "o2").mkdir()
    summary = run_video(VideoTask(str(clip), "c", str(tmp_path / "o2"), s, None, "r2"))
    assert summary["status"] == "done" and not (tmp_path / "o2" / "c.boxes.txt").exists()  # not renamed yet
    Path(summary["partials"]["boxes"]).unlink()
    with pytest.raises(WriteError, match="vanished"):
        commit_outputs(summary, tmp_path / "o2")
    man = Manifest(tmp_path / "m.jsonl")
    man.append({"input": str(clip), "name": "c", "status": "failed", "permanent": False, "settings_hash": s.digest(),
                **input_stat(clip)})
    assert man.known_failure(clip, "c", s.digest()) is None  # tried again next run
    # a bad video is permanent
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"not a video" * 50)
    summary = run_video(VideoTask(str(bad), "bad", str(tmp_path / "o3"), s, None, "r3"))
    assert summary["status"] == "failed" and summary["permanent"] is True


def test_without_dask_says_how_to_get_it(tmp_path: Path) -> None:
    code = ("import sys; sys.modules['distributed'] = None\n"
            "from fastdet.cli.main import main\n"
            f"sys.exit(main(['batch', {str(tmp_path)!r}, '--out', {str(tmp_path / 'o')!r}]))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install fastdet[cluster]" in lines[0]
    assert not (tmp_path / "o").exists()


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
def first_run(clips: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, subprocess.CompletedProcess]:
    out = tmp_path_factory.mktemp("out")
    r = batch(clips, "--out", out, "--workers", "2", "--json", "--video", "--table", out / "boxes.parquet",
              "--no-progress")
    return out, r


def test_batch_boxes_identical_to_video(clips: Path, first_run, tmp_path: Path) -> None:
    out, _ = first_run
    procs = {}
    for name, clip in (("road", clips / "road.mp4"), ("oncoming", clips / "day2" / "oncoming.mp4")):
        procs[name] = subprocess.Popen(FASTDET + ["video", str(clip), "--boxes", str(tmp_path / f"{name}.txt"),
                                                  "--json", str(tmp_path / f"{name}.jsonl"), "--no-progress"],
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    for name, p in procs.items():
        assert p.wait(timeout=TIMEOUT) == 0, p.stderr.read()
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
    r = batch(clips, "--out", out, "--workers", "2", "--json", "--no-track", "--no-progress")
    assert r.returncode == 1, r.stderr
    lines = manifest_lines(out)
    assert sorted(e["name"] for e in lines[n_lines:]) == ["broken", "oncoming", "road"]
    last = {e["name"]: e for e in lines[n_lines:]}["road"]
    assert last["settings"]["outputs"] == ["boxes", "json"] and last["settings"]["tracker"] is None
    ref = out.parent / "road_no_track.txt"
    v = subprocess.run(FASTDET + ["video", str(clips / "road.mp4"), "--no-track", "--boxes", str(ref),
                                  "--no-progress"], capture_output=True, text=True, timeout=TIMEOUT)
    assert v.returncode == 0, v.stderr
    assert (out / "road.boxes.txt").read_bytes() == ref.read_bytes()
    assert set(read_predictions(ref).ids.tolist()) == {-1}

    # --overwrite: the same settings as the first run, but everything is done again
    before = {f.name: f.stat().st_ino for f in out.glob("*.boxes.*")}
    r = batch(clips, "--out", out, "--workers", "2", "--overwrite", "--json", "--video", "--no-progress")
    assert r.returncode == 1, r.stderr
    redone = {e["name"]: e for e in manifest_lines(out)[len(lines):]}
    assert set(redone) == {"road", "oncoming", "broken"}
    assert all(f.stat().st_ino != before[f.name] for f in out.glob("*.boxes.*"))
    assert (out / "road.boxes.txt").read_bytes() != ref.read_bytes()  # with track ids again


def test_batch_bad_arguments_one_line(tmp_path: Path, clips: Path, capsys: pytest.CaptureFixture) -> None:
    for args, msg in (([tmp_path / "nope"], "file not found"),
                      ([clips, "--table", tmp_path / "t.xlsx"], ".parquet or .csv"),
                      ([clips, "--model", tmp_path / "m.npz"], "model file not found"),
                      ([clips, "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--workers")):
        assert main(["batch", *map(str, args), "--out", str(tmp_path / "o")]) == 2, args
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and msg in err, (args, err)
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------------------------------
# a killed worker, a killed batch


@pytest.fixture(scope="module")
def long_clips(tmp_path_factory: pytest.TempPathFactory, data: Path) -> tuple[Path, dict[str, bytes]]:
    """Five 30-frame clips and the boxes file of each (run in this process, as a task)."""
    d = tmp_path_factory.mktemp("long")
    src = data / "videos" / "test_small1.mp4"
    for k in range(5):
        cut(src, d / f"c{k}.mp4", 10 * k, 30)
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
        in_progress = {m["name"]: m["token"] for m in
                       (re.match(r"^\.?(?P<name>c\d)\.boxes\.(?P<token>[0-9a-f]{16})", p.name) for p in running)}
        workers[0].send_signal(signal.SIGKILL)
        workers[0].wait(timeout=30)
        _, stderr = b.communicate(timeout=TIMEOUT)
        assert b.returncode == 0, stderr
        entries = {e["name"]: e for e in manifest_lines(out)}
        assert {n: e["status"] for n, e in entries.items()} == {n: "done" for n in want}
        for name, content in want.items():
            assert (out / f"{name}.boxes.txt").read_bytes() == content, name
        # the killed worker's video was run again: its final attempt is not the one seen running
        assert any(entries[n]["token"] != tok for n, tok in in_progress.items())
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

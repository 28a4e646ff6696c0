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

from fastdet.batch.inputs import expand_inputs, output_names
from fastdet.batch.job import remove_partials
from fastdet.batch.manifest import Manifest, input_stat
from fastdet.batch.progress import BatchProgress
from fastdet.batch.settings import Settings, output_paths
from fastdet.batch.task import PARTIAL_DIR, VideoTask, partial_path, run_video
from fastdet.cli.main import main
from fastdet.errors import DataError
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
    d = out / PARTIAL_DIR
    return sorted(d.iterdir()) if d.is_dir() else []


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


def test_remove_partials_only_of_the_named_videos(tmp_path: Path) -> None:
    s = Settings.create(video=True)
    mine = [partial_path(tmp_path, p, "0123456789abcdef") for p in output_paths(tmp_path, "a", s).values()]
    other = partial_path(tmp_path, output_paths(tmp_path, "a.b", s)["boxes"], "0123456789abcdef")
    (tmp_path / PARTIAL_DIR).mkdir()
    for p in [*mine, other, tmp_path / PARTIAL_DIR / ".a.annotated.0123456789abcdef.partial.mp4"]:
        p.write_bytes(b"")
    remove_partials(tmp_path, ["a"])
    assert partials(tmp_path) == [other]


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
        summary = run_video(VideoTask(str(d / f"c{k}.mp4"), f"c{k}", str(ref), s))
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
    # whatever has a final name is complete; nothing half-written is left behind
    for f in out.glob("*.boxes.txt"):
        assert f.read_bytes() == want[f.name.split(".")[0]], f.name
    assert not partials(out)

    r = batch(clips, "--out", out, "--workers", "2", "--no-progress")
    assert r.returncode == 0, r.stderr
    skipped = next(line for line in r.stdout.splitlines() if line.startswith("skipped"))
    assert int(skipped.split()[1]) == len(done_before)
    for name, content in want.items():
        assert (out / f"{name}.boxes.txt").read_bytes() == content, name

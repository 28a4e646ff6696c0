"""``python -m fastdet eval``: keyframes (CLIP.frames beside the ground truth, --keyframes) and
the report over every annotated clip (--all)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from fastdet.cli import eval as ev
from fastdet.cli import main
from fastdet.detections import Detections
from tests.media import write_video

# keyframes 1 and 11 of a 640x360 clip: one target on each (60 and 150 px wide at 360 rows,
# i.e. 120 and 300 reference pixels), an ignore region on 11
GT = "1,1,100,100,60,40,1,1,1\n11,1,110,100,150,80,1,1,1\n11,1000,500,100,30,20,0,1,1\n"
# a hit on 1, a false alarm on 11, and two boxes on frame 5 (not a keyframe)
PRED = ("1,-1,100,100,60,40,0.9,-1,-1,-1\n11,-1,300,250,60,40,0.8,-1,-1,-1\n"
        "5,-1,0,0,60,40,0.9,-1,-1,-1\n5,-1,100,100,60,40,0.9,-1,-1,-1\n")


@pytest.fixture()
def clip(tmp_path):
    ann = tmp_path / "annotations"
    ann.mkdir()
    (ann / "cam.gt.txt").write_text(GT)
    (ann / "cam.frames").write_text("1\n11\n")
    (tmp_path / "preds").mkdir()
    (tmp_path / "preds" / "cam.txt").write_text(PRED)
    return tmp_path


def test_keyframes_beside_the_ground_truth_are_used(clip, capsys):
    gt, pred = clip / "annotations" / "cam.gt.txt", clip / "preds" / "cam.txt"
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["frames"], d["tp"], d["fp"], d["fn"], d["num_outside"]) == (2, 1, 1, 1, 2)
    assert d["keyframes"] is True and d["keyframes_file"] == str(clip / "annotations" / "cam.frames")
    assert d["fp_per_frame"] == 0.5
    assert main(["eval", "--gt", str(gt), "--pred", str(pred)]) == 0
    out = capsys.readouterr().out
    assert "2 keyframes" in out and "2 predictions on frames that are not keyframes were not evaluated" in out


def test_keyframes_option(clip, tmp_path, capsys):
    gt, pred = clip / "annotations" / "cam.gt.txt", clip / "preds" / "cam.txt"
    kf = tmp_path / "more.frames"
    kf.write_text("1\n5\n11\n")  # frame 5 listed: annotated, without vehicles
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--keyframes", str(kf), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert (d["frames"], d["tp"], d["fp"], d["num_outside"]) == (3, 1, 3, 0)
    kf.write_text("1\n")  # ground truth on 11 is not listed: the files disagree
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--keyframes", str(kf)]) == 2
    err = capsys.readouterr().err
    assert "ground truth on frame 11, which is not one of the keyframes" in err and len(err.strip().splitlines()) == 1
    kf.write_text("1\nx\n")
    assert main(["eval", "--gt", str(gt), "--pred", str(pred), "--keyframes", str(kf)]) == 2
    assert "more.frames: line 2" in capsys.readouterr().err


def test_all_from_prediction_files(clip, tmp_path, capsys):
    (clip / "videos").mkdir()
    write_video(clip / "videos" / "cam.mp4", 3, w=640, h=360)
    out = tmp_path / "report.json"
    assert main(["eval", "--all", "--data", str(clip), "--pred-dir", str(clip / "preds"), "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert "| cam | 2 kf | 2 | 0.50 | 0.50 | **0.50** |" in table and f"report written to {out}" in table
    assert "| 0/0 |" not in table and table.splitlines()[2].endswith("| - | - | 1/2 |")
    rep = json.loads(out.read_text())
    assert rep["settings"] == {"iou": 0.5, "pred_dir": str(clip / "preds")}
    cam = rep["clips"]["cam"]
    assert (cam["tp"], cam["fp"], cam["frames"], cam["frame_rows"]) == (1, 1, 2, 360)
    assert [(b["bin"], b["found"], b["total"]) for b in cam["recall_by_width"]] == [
        ("<60", 0, 0), ("60-120", 0, 0), (">=120", 1, 2)]
    assert not list(tmp_path.glob(".report*"))
    assert main(["eval", "--all", "--data", str(clip), "--pred-dir", str(clip / "preds"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == rep


def test_all_runs_the_pipeline_on_every_clip(clip, monkeypatch, capsys):
    (clip / "videos").mkdir()
    write_video(clip / "videos" / "cam.mp4", 3, w=640, h=360)
    seen = []

    def fake_iter(path, config, progress=True, **kw):
        seen.append((path, config.horizon))
        yield 1, Detections(np.array([[100, 100, 160, 140]], np.int32), np.array([0.9], np.float32))

    monkeypatch.setattr(ev, "iter_video_detections", fake_iter)
    assert main(["eval", "--all", "--data", str(clip), "--horizon", "0.6", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert seen == [(str(clip / "videos" / "cam.mp4"), 0.6)]
    assert rep["settings"]["horizon"] == 0.6 and rep["settings"]["model"] == "bundled"
    assert (rep["clips"]["cam"]["tp"], rep["clips"]["cam"]["fp"]) == (1, 0)


@pytest.mark.parametrize("argv, words", [
    (["--all", "--gt", "g.txt"], "--all scores every annotated clip"),
    (["--gt", "g.txt", "--pred", "p.txt", "--out", "r.json"], "only apply with --all"),
    (["--pred", "p.txt"], "give --gt GT.txt and one of --pred"),
    (["--gt", "g.txt"], "give --gt GT.txt and one of --pred"),
    (["--all", "--clips", "nope"], "--clips: no annotated clip named nope (have: cam)"),
    (["--all", "--pred-dir", "PREDS", "--no-oncoming"], "not with --pred-dir"),
    (["--gt", "g.txt", "--pred", "p.txt", "--no-track"], "only apply with --video"),
    (["--all", "--pred-dir", "EMPTY"], "no predictions for clip cam"),
    (["--all", "--out", "/no/such/folder/r.json"], "output folder /no/such/folder does not exist"),
])
def test_usage_errors_are_one_line(clip, argv, words, capsys):
    (clip / "videos").mkdir()
    (clip / "videos" / "cam.mp4").write_bytes(b"")
    (clip / "empty").mkdir()
    argv = [a.replace("PREDS", str(clip / "preds")).replace("EMPTY", str(clip / "empty")) for a in argv]
    if "--all" in argv:
        argv += ["--data", str(clip)]
    assert main(["eval", *argv]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1, err


def test_all_without_clips(tmp_path, capsys):
    (tmp_path / "annotations").mkdir()
    assert main(["eval", "--all", "--data", str(tmp_path)]) == 2
    assert "no annotated clips" in capsys.readouterr().err


def test_frames_bad_specs_one_line(capsys):
    from fastdet import cli as _cli

    for spec, match in (("bogus:/x", "FORMAT:PATH"), ("voc:/nonexistent-set", "not found"),
                        ("kitti:/x,every=3", "")):
        rc = _cli.main(["eval", "--frames", spec])
        err = capsys.readouterr().err
        assert rc == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err and match in err, err


def test_frames_scores_a_voc_set(data, tmp_path, capsys):
    """One dawn_fog picture as a VOC set of its own: the row of the table and the JSON report."""
    import json as _json
    import shutil

    from fastdet import cli as _cli

    root = tmp_path / "fog"
    (root / "images").mkdir(parents=True)
    (root / "voc").mkdir()
    src = data / "frames" / "dawn_fog"
    shutil.copy(src / "images" / "foggy-001.jpg", root / "images")
    shutil.copy(src / "voc" / "foggy-001.xml", root / "voc")
    out = tmp_path / "r.json"
    assert _cli.main(["eval", "--frames", f"voc:{root}", "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert "voc:fog" in table and "1 pic" in table
    rep = _json.loads(out.read_text())["pictures"]["voc:fog"]
    assert rep["pictures"] == 1 and rep["complete"] is True and rep["targets"] >= 1
    # --no-refine: the first stage alone, every box it finds in the picture scored
    import cv2

    from fastdet.config.picture import FIRST_STAGE_ONLY
    from fastdet.video.picture import PictureDetector

    assert _cli.main(["eval", "--frames", f"voc:{root}", "--out", str(out), "--no-refine"]) == 0
    rep = _json.loads(out.read_text())["pictures"]["voc:fog"]
    n = len(PictureDetector(config=FIRST_STAGE_ONLY).detect(cv2.imread(str(root / "images" / "foggy-001.jpg"))))
    assert rep["tp"] + rep["fp"] + rep["dropped"] == n


@pytest.mark.parametrize("target", ["annotations/cam.frames", "annotations/other.gt.txt", "frames/dawn_fog/x.json",
                                    "teacher/t.teacher.txt", "NEW_KEYFRAMES"])
def test_all_never_writes_its_report_over_what_it_reads(clip, capsys, monkeypatch, target):
    """Issue 34 (2): ``eval --all --out D/annotations/CLIP.frames`` replaced the keyframe list
    with the JSON report. Every file --all reads is an input: the clips' keyframe lists (also
    one a clip does not have yet: the report would become it), the data folder's other
    annotations and teacher files, the picture-set folders."""
    (clip / "videos").mkdir()
    write_video(clip / "videos" / "cam.mp4", 3, w=640, h=360)
    (clip / "annotations" / "other.gt.txt").write_text(GT)  # no video: not a clip, but read by the sets
    (clip / "frames" / "dawn_fog").mkdir(parents=True)
    (clip / "teacher").mkdir()
    (clip / "teacher" / "t.teacher.txt").write_text("x\n")
    # the run itself is faked: only where its report goes is tested
    monkeypatch.setattr(ev, "_picture_sets", lambda args, shared: [])
    monkeypatch.setattr(ev, "iter_video_detections", lambda *a, **k: iter([]))
    argv = ["eval", "--all", "--data", str(clip), "--clips", "cam"]
    if target in ("annotations/cam.frames", "NEW_KEYFRAMES"):
        argv += ["--pred-dir", str(clip / "preds")]
    if target == "NEW_KEYFRAMES":
        (clip / "annotations" / "cam.frames").unlink()
        target = "annotations/cam.frames"
    out = clip / target
    before = out.read_bytes() if out.exists() else None
    rc = main([*argv, "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert (out.read_bytes() if out.exists() else None) == before


def test_a_video_shorter_than_its_ground_truth_is_said_and_scored_on_its_frames(tmp_path, monkeypatch, capsys):
    """Issue 34 (5): a 20-frame clip against an 88-frame ground truth scored frames 21-88 as
    misses (recall 0.16) without a word."""
    gt = tmp_path / "g.txt"
    gt.write_text("1,1,100,100,60,40\n3,1,100,100,60,40\n20,1,100,100,60,40\n")
    video = write_video(tmp_path / "c.mp4", 3, w=640, h=360)

    def fake_iter(path, config, progress=True, **kw):
        for f in (1, 2, 3):
            yield f, Detections(np.array([[100, 100, 160, 140]], np.int32), np.array([0.9], np.float32))

    monkeypatch.setattr(ev, "iter_video_detections", fake_iter)
    assert main(["eval", "--gt", str(gt), "--video", str(video), "--json"]) == 0
    out, err = capsys.readouterr()
    assert "the video ended at frame 3, before the ground truth's last frame 20; only frames 1-3 are scored" in err
    res = json.loads(out)
    assert res["recall"] == 1.0, res

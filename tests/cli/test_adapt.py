"""``python -m fastdet adapt``: a small end-to-end run that writes a loadable model holding its
summary, a stopped run that resumes without labelling a finished video again, stop signals,
and every bad input ending in one line before any work."""
from __future__ import annotations

import dataclasses
import os
import re
import signal
from pathlib import Path

import numpy as np
import pytest

from fastdet.cli import adapt as adapt_cli
from fastdet.cli import kept_aside
from fastdet.cli.main import main
from fastdet.config import PipelineConfig
from fastdet.detect.regressor import carried_regressor, load_regressor
from fastdet.model import load_model
from fastdet.teacher.yolox import TeacherBoxes
from fastdet.video import VideoDetector
from fastdet.video.box_stages import HeatStage
from fastdet.video.detector import BOXES_KEY, HORIZON_KEY, ONCOMING_KEY, make_detector
from fastdet.video.nmsboxes import NmsStage
from tests.media import leftovers, write_video
from tests.teacher.onnx_bytes import FLOAT, write_identity_model

pytest.importorskip("onnxruntime")


@pytest.fixture(scope="module")
def teacher(yolox_nano: Path) -> Path:
    return yolox_nano


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _adapt(*args: object) -> int:
    return main(["adapt", *map(str, args), "--no-progress"])


# ------------------------------------------------------------------------------ bad input


def test_bad_inputs_are_one_line_before_any_work(teacher, data, tmp_path, capsys):
    small = write_video(tmp_path / "small.mp4", 20)
    other = write_video(tmp_path / "other.mp4", 20, w=160, h=120)
    empty_dir = tmp_path / "empty"
    empty_dir.mkdir()
    not_video = tmp_path / "nothing.mp4"
    not_video.write_bytes(b"not a video")
    text_teacher = tmp_path / "t.onnx"
    text_teacher.write_text("not a model")
    identity = write_identity_model(tmp_path / "id.onnx", [((1, 3, "h", "w"), FLOAT)])
    out = tmp_path / "cam.npz"
    inside = Path(adapt_cli.__file__).resolve().parents[1] / "models" / "mine.npz"
    cases = [
        ((small, other, "--teacher", teacher, "-o", out), "160x120, .*small.mp4's are 320x240"),
        ((empty_dir, "--teacher", teacher, "-o", out), "no video files in this folder"),
        ((not_video, "--teacher", teacher, "-o", out), "nothing.mp4: not a video"),
        ((small, "--teacher", text_teacher, "-o", out), "t.onnx"),
        ((small, "--teacher", identity, "-o", out), "id.onnx: not a YOLOX-style detector"),
        ((small, "--teacher", tmp_path / "missing.onnx", "-o", out), "missing.onnx: file not found"),
        ((small, "-o", out), "give --teacher MODEL.onnx .* or --frames SPEC"),
        ((small, "--teacher", teacher, "--frames", "mot:x", "-o", out), "one of them"),
        ((small, "--teacher", teacher, "-o", inside), "inside the installed fastdet package"),
        ((small, "--teacher", teacher, "-o", tmp_path / "cam.txt"), "must end in .npz"),
        ((small, "--teacher", teacher, "-o", tmp_path / "no" / "cam.npz"), "does not exist"),
        ((small, "--teacher", teacher, "-o", out, "--data", tmp_path), "crop folder .* not found"),
        ((small, "--frames", "nope:x", "-o", out), "nope"),
        ((write_video(tmp_path / "one.mp4", 1), "--teacher", teacher, "-o", out), "too short"),
        ((small, "--teacher", teacher, "-o", out, "--workers", 2, "--scheduler", "tcp://h:1"), "--workers is for"),
        ((small, "--frames", "mot:x", "-o", out, "--workers", 2), "need --teacher"),
        ((small, "--teacher", teacher, "-o", out, "--scheduler", "nonsense"), "not a scheduler address"),
    ]
    for args, msg in cases:
        assert _adapt(*args) == 2, (args, msg)
        line = _one_line(capsys.readouterr().err)
        assert line.startswith("fastdet adapt: error: ") and re.search(msg, line), (msg, line)
        assert not out.exists() and not inside.exists()
        assert not (tmp_path / ".cam.adapt").exists(), msg  # nothing made before the checks passed
    assert not leftovers(tmp_path)


# ----------------------------------------------------------------------- stop and resume


class _Teacher:
    """Stands in for the CNN's ``detect``: one car in every frame, calls counted; sends
    ``signum`` to this process at call ``stop_at`` (1-based)."""

    def __init__(self, stop_at: int | None = None, signum: int = signal.SIGINT) -> None:
        self.calls = 0
        self.stop_at, self.signum = stop_at, signum

    def __call__(self, frame: np.ndarray) -> TeacherBoxes:
        self.calls += 1
        if self.calls == self.stop_at:
            os.kill(os.getpid(), self.signum)
        h, w = frame.shape[:2]
        return TeacherBoxes(np.array([[w * 0.3, h * 0.4, w * 0.6, h * 0.8]]), np.array([0.9], np.float32),
                            np.array([2], np.int16))


def test_a_stopped_run_resumes_without_labelling_a_finished_video_again(teacher, data, tmp_path, capsys,
                                                                         monkeypatch):
    from fastdet.teacher.yolox import TeacherDetector
    from fastdet.train import adapt

    footage = tmp_path / "cam"
    footage.mkdir()
    write_video(footage / "a.mp4", 30)
    write_video(footage / "b.mp4", 30)
    out = tmp_path / "cam.npz"
    args = (footage, "--teacher", teacher, "-o", out, "--every", "5")
    per_clip = 5 + 6  # 1, 6, ..., 21 before the kept-aside stretch (frames 25-30), each of which is labelled

    # 1. Ctrl-C while the second video is labelled: the first one's labels are kept, nothing else
    first = _Teacher(stop_at=per_clip + 2)
    monkeypatch.setattr(TeacherDetector, "detect", lambda _self, frame: first(frame))
    assert _adapt(*args) == 130
    err = capsys.readouterr().err
    assert "interrupted (SIGINT); 1 of 2 videos labelled" in err and "no model written" in err
    assert first.calls == per_clip + 2
    labels = list((tmp_path / ".cam.adapt").glob("labels-*/*.teacher.txt"))
    assert [p.name.split("-")[0] for p in labels] == ["a"] and not out.exists()

    # 2. the next run labels the second video only; a SIGTERM in the next step ends it
    def stop_now(*_a: object, **_k: object) -> None:
        os.kill(os.getpid(), signal.SIGTERM)

    second = _Teacher()
    monkeypatch.setattr(TeacherDetector, "detect", lambda _self, frame: second(frame))
    monkeypatch.setattr(adapt, "camera_crops", stop_now)
    assert _adapt(*args) == 143
    assert "interrupted (SIGTERM)" in capsys.readouterr().err
    assert second.calls == per_clip and not out.exists()
    assert sorted(p.name.split("-")[0] for p in (tmp_path / ".cam.adapt").glob("labels-*/*.teacher.txt")) == \
        ["a", "b"]

    # 3. and the one after it labels nothing
    third = _Teacher()
    monkeypatch.setattr(TeacherDetector, "detect", lambda _self, frame: third(frame))
    assert _adapt(*args) == 143
    assert third.calls == 0 and not out.exists()
    assert f"teacher labels of {per_clip} frames read from" in capsys.readouterr().out
    assert not leftovers(tmp_path) and not leftovers(tmp_path / ".cam.adapt")


# ----------------------------------------------------------------------------- end to end


@pytest.mark.slow
def test_adapt_writes_a_model_with_its_summary(teacher, data, tmp_path, capsys, monkeypatch):
    """test_video (38 frames): 6 frames trained on, the last 8 kept aside; a reduced crop set
    (and the camera's box regressor fitted on its dozen vehicles, below the real floor)."""
    from fastdet.train import adapt as train_adapt

    monkeypatch.setattr(train_adapt, "MIN_REGRESSOR_VEHICLES", 2)
    config = adapt_cli._config  # the side-view component fitted on the clip's few wide vehicles
    monkeypatch.setattr(adapt_cli, "_config", lambda args: dataclasses.replace(config(args), side_min_vehicles=1))
    out = tmp_path / "tv.npz"
    assert _adapt(data / "videos" / "test_video.mp4", "--teacher", teacher, "-o", out, "--max-frames", "10",
                  "--max-per-folder", "20", "--offsets", "0", "1") == 0
    text = capsys.readouterr().out
    assert "agreement with the teacher labels on the kept-aside frames" in text and f"wrote {out}" in text
    model = load_model(out)  # allow_pickle=False: the format video / image / batch --model read
    s = model.metadata["adapt"]
    assert s["frames"]["trained"] == 6 and s["frames"]["kept_aside_labelled"] == 8  # every kept-aside frame
    assert s["frames"]["kept_aside_read"] == 8 and s["labelled_by"] == "teacher"
    assert s["offset"] in (0.0, 1.0) and model.metadata["offset"] == s["offset"]
    assert set(s["seconds"]) >= {"label", "crops", "hard_negatives", "train", "regressor", "operating_point", "total"}
    # the camera's box regressor, fitted on its labelled vehicles, rides in the file and the
    # pipeline refines with it
    reg = carried_regressor(model)
    assert reg is not None and s["regressor_fit"]["samples"] > 0 and "box regressor: fitted on" in text
    assert not np.array_equal(reg.coef, load_regressor().coef)
    np.testing.assert_array_equal(VideoDetector(config=PipelineConfig(model=str(out))).refiner.coef, reg.coef)
    for when in ("before", "after"):
        a = s["agreement"][when]
        assert 0 <= a["f1"] <= 1 and a["tp"] + a["fn"] >= 2 and a["ms_per_frame"] > 0
    # the strictest offset within one standard error of the best F1 (over the kept-aside frames)
    tried = s["boxes_tried"][s["boxes"]]
    assert tried["offset"] == s["offset"] and tried["offset"] >= tried["best_offset"]
    assert s["offsets_f1"][f"{s['offset']:g}"] >= tried["best_f1"] - tried["f1_se"]
    if s["side"]["offset"] is None:
        assert s["agreement"]["after"]["f1"] == s["offsets_f1"][f"{s['offset']:g}"]
    assert "by the one-standard-error rule" in text
    # the camera's horizon: the flow's and the one its labelled vehicles imply; the number recorded
    # only where the latter was chosen
    hz = s["horizon"]
    assert hz["chosen"] in ("flow", "boxes") and "horizon" in s["seconds"] and "horizon: the flow's" in text
    assert (model.metadata.get(HORIZON_KEY) == hz["boxes"]) if hz["chosen"] == "boxes" else (
        HORIZON_KEY not in model.metadata)
    # both box formations tried; the chosen one (at least as good as the other) is recorded in
    # the model file, and the pipeline makes its boxes that way
    assert set(s["boxes_tried"]) == {"heat", "nms"} and model.metadata[BOXES_KEY] == s["boxes"]
    # no bundled oncoming model beside the camera's own (chosen and written that way)
    assert model.metadata[ONCOMING_KEY] is False
    assert make_detector(PipelineConfig(model=str(out))).oncoming_model is None
    f1s = {b: (-1 if v["best_f1"] is None else v["best_f1"]) for b, v in s["boxes_tried"].items()}
    assert "boxes tried (F1 at their best offset)" in text
    # the side-view component: fitted, its offsets (and leaving it out) tried with the window boxes
    side = s["side"]
    assert side["fit"]["vehicles"] >= 1 and side["fit"]["positives"] > 0 and "side-view component: fitted" in text
    assert set(side["offsets_f1"]) == {"0", "1", "2", "3", "4", "6", "inf"}
    if side["offset"] is None:  # left out: the formation of best F1 without it
        assert model.side is None and f1s[s["boxes"]] == max(f1s.values()) and "chosen: left out" in text
    else:  # kept: window boxes, at the F1 the replay gave them
        assert ("instead_of" not in side) or f"(with the side-view component, instead of {side['instead_of']})" in text
        assert model.side is not None and model.side.config.window_height == 32 and s["boxes"] == "nms"
        assert s["agreement"]["after"]["f1"] == side["offsets_f1"][f"{side['offset']:g}"]
        assert len(make_detector(PipelineConfig(model=str(out))).components) == 1
    stage = NmsStage if s["boxes"] == "nms" else HeatStage
    assert VideoDetector(config=PipelineConfig(model=str(out))).stage(stage) is not None
    assert model.metadata["training"]["data"]["hard_negatives"] > 0
    # the camera's crops joined the fit once each, of weight 4 (not repeated 4 times)
    assert model.metadata["training"]["data"]["extra_positives"] == s["crops"]["positives"] > 0
    assert model.metadata["training"]["extra_weight"] == s["crops"]["weight"] == 4
    # the model file is what `image --model` takes
    assert main(["image", str(data / "test_images" / "test1.jpg"), "--model", str(out),
                 "-o", str(tmp_path / "x.jpg")]) == 0
    assert (tmp_path / "x.jpg").is_file()
    assert not (tmp_path / ".tv.adapt" / "operating-point").exists() and not leftovers(tmp_path)


def test_the_models_own_boxes_are_the_video_pipelines_window_boxes(data):
    """own_window_boxes at the file's horizon gives a frame the boxes the video pipeline makes from
    the same model's windows (boxes='nms', the horizon primed from the file), with no tracker, refinement,
    own-vehicle or plausibility stage and the full search; on a frame where it finds some."""
    from fastdet.io.reader import FrameReader
    from fastdet.video.run import iter_video_detections

    video = str(data / "videos" / "test_video.mp4")
    from fastdet.video.run import file_horizon

    boxes = adapt_cli.own_window_boxes(load_model(), file_horizon(video))
    cfg = PipelineConfig(oncoming=False, boxes="nms", tracker=None, refine=None, guided=None, own_vehicle=None,
                         split=None, plausible=None)
    runs = dict(iter_video_detections(video, cfg, frames=6, progress=False))
    reader = FrameReader(video, 0, 6)
    found = 0
    for f, frame, _ in reader:
        got = boxes(frame)
        assert got.dtype == np.int32 and got.shape[1:] == (4,)
        np.testing.assert_array_equal(np.unique(got, axis=0), np.unique(runs[f].boxes, axis=0))
        found += len(got)
    reader.close()
    assert found > 0


def test_the_side_components_summary_line_says_what_was_chosen():
    none = {"fit": {"vehicles": 3, "skipped": "3 labelled vehicles of 1.4:1 and wider to fit it on, fewer than 20"},
            "offset": None}
    assert adapt_cli.side_line(none) == ("side-view component: none (3 labelled vehicles of 1.4:1 and wider to fit "
                                         "it on, fewer than 20)")
    fit = {"vehicles": 30, "positives": 480, "negatives": 900, "hard_negatives": 120}
    no_nms = adapt_cli.side_line({"fit": fit, "offset": None})
    assert no_nms.startswith("side-view component: fitted on 30 vehicles (480 positive") and "left out" in no_nms
    line = adapt_cli.side_line({"fit": fit, "offset": 3.0, "offsets_f1": {"0": 0.5, "3": 0.61, "inf": 0.55}})
    assert "0 0.50, 3 0.61, left out 0.55; chosen: offset 3" in line


def test_the_horizon_line_says_what_was_chosen():
    skipped = {"flow": 0.48, "boxes": None, "chosen": "flow", "skipped": "too few"}
    assert adapt_cli.horizon_line(skipped) == ("horizon: the flow's 0.480, the labelled vehicles' none; kept the "
                                               "flow's (too few)")
    chosen = {"flow": None, "boxes": 0.5604, "chosen": "boxes", "f1": {"flow": 0.05, "boxes": 0.41}, "f1_se": 0.05}
    assert adapt_cli.horizon_line(chosen) == ("horizon: the flow's the reference, the labelled vehicles' 0.560; F1 on "
                                              "the kept-aside frames 0.05 / 0.41 (+- 0.05); chosen: the labelled "
                                              "vehicles'")


@pytest.mark.parametrize("f1_flow, f1_boxes, se, chosen", [(0.30, 0.41, 0.05, "boxes"), (0.37, 0.41, 0.05, "flow"),
                                                           (0.45, 0.41, 0.01, "flow")])
def test_the_boxes_horizon_is_kept_only_above_the_flows_by_more_than_an_error(
        f1_flow, f1_boxes, se, chosen, tmp_path, monkeypatch):
    """choose_horizon replays the kept-aside frames at the flow's horizons (each video its own) and
    at the labelled vehicles' (here a stand-in for the replay: an F1 per horizon) and keeps the
    vehicles' only when its F1 less its standard error is above the flow's; near every video's
    flow horizon (the reference's where the flow gave none), or without kept-aside frames, it is
    not tried. The line is fitted on the footage's frames only: a still of another camera is left
    out."""
    from contextlib import contextmanager

    from fastdet.labels.picture import AnnotatedPicture
    from fastdet.train import adapt as train_adapt
    from fastdet.train.operating_point import Agreement, FormationChoice

    def frames(video: str, horizon: float, n: int = 5) -> list[AnnotatedPicture]:
        boxes = _horizon_boxes(horizon)
        return [AnnotatedPicture("teacher", "c", f"{i}", Path(video), 1280, 720, targets=boxes[i::n], frame=i + 1)
                for i in range(n)]

    pictures = frames("c1.mp4", 0.55) + frames("c2.mp4", 0.55)
    still = AnnotatedPicture("user", "other", "s", Path("s.png"), 1280, 720, targets=_horizon_boxes(0.2))
    clips = (train_adapt.Clip("c1.mp4", "c1", 100, 81), train_adapt.Clip("c2.mp4", "c2", 100, 81))
    footage = train_adapt.Footage(clips, 5, 1, (1280, 720))
    asked: list[dict] = []

    def replay(model, footage_, run, folder, offsets, formations, progress, seed):
        asked.append(run)
        f1 = f1_flow if run["c1"] == 0.40 else f1_boxes  # the flow's, else the vehicles'
        tp = round(100 * f1)  # F1 = 2 tp / (2 tp + fp + fn) = tp / 100 with fp = fn = 100 - tp
        agreement = Agreement(tp, 100 - tp, 100 - tp, 1.0, 10)
        return "nms", 1.0, {"nms": FormationChoice(1.0, {0.0: agreement, 1.0: Agreement(0, 1, 1, 1.0, 10)},
                                                   0.0, se)}

    monkeypatch.setattr(kept_aside._op, "choose_operating_point", replay)
    monkeypatch.setattr(kept_aside, "holdout_lanes", lambda held, frames, at: dict(at))
    held = {"c1": pictures[:1], "c2": []}
    config = kept_aside.AdaptConfig()
    flows = {"c1": 0.40, "c2": 0.53}
    summary, hz = kept_aside.choose_horizon(None, footage, pictures + [still], held, flows, config, tmp_path, False, {})
    assert asked[0] == flows and asked[1] == {"c1": pytest.approx(0.55, abs=0.01), "c2": pytest.approx(0.55, abs=0.01)}
    assert summary["chosen"] == chosen and summary["flow"] == 0.40
    assert summary["boxes"] == pytest.approx(0.55, abs=0.01) and summary["f1_se"] == se
    assert summary["f1"] == {"flow": f1_flow, "boxes": f1_boxes}  # at the best offset, the one of the error
    assert hz == (summary["boxes"] if chosen == "boxes" else None)
    for near in ({"c1": 0.53, "c2": 0.52}, {"c1": None, "c2": 0.56}):  # None: the reference, 0.585
        s, hz = kept_aside.choose_horizon(None, footage, pictures, held, near, config, tmp_path, False, {})
        assert hz is None and "within 0.05" in s["skipped"] and len(asked) == 2
    s, hz = kept_aside.choose_horizon(None, footage, pictures, {"c1": [], "c2": []}, flows, config, tmp_path, False, {})
    assert hz is None and "no labelled frame kept aside" in s["skipped"] and len(asked) == 2
    s, hz = kept_aside.choose_horizon(None, footage, [still], held, flows, config, tmp_path, False, {})
    assert hz is None and s["boxes"] is None and "fewer than" in s["skipped"]
    # the stretches adapt read once for this and the operating point: not read again
    @contextmanager
    def read_again(*a, **k):
        raise AssertionError("the kept-aside stretches read a second time")
        yield {}

    monkeypatch.setattr(kept_aside, "held_stretches", read_again)
    s, hz = kept_aside.choose_horizon(None, footage, pictures, held, flows, config, tmp_path, False, {})
    assert s["chosen"] == chosen and len(asked) == 4


def _horizon_boxes(horizon: float) -> np.ndarray:
    from tests.video.test_horizon import _perspective_boxes

    return _perspective_boxes(200, horizon, 720)

"""tools/studies/adapt_seeds.py: a clip's row holds each seed's human keyframe figures as
``fastdet eval --video --model`` gives them, their mean and spread; a seed whose adapt refused is
named and left out."""
from __future__ import annotations

import json
import shutil

import pytest

from fastdet import cli
from fastdet.config.models import DEFAULT_MODEL_PATH
from fastdet.eval.clips import annotated_clips
from tools.studies.adapt_seeds import SeedScore, adapt_clip, row, study


def test_rows_are_the_eval_command_s_figures_and_their_mean(data, tmp_path, capsys):
    clip = {c.name: c for c in annotated_clips(data)}["boston_street"]  # 40 frames, 8 keyframes
    runs = []

    def fake_adapt(c, seed, out, data_dir, extra):
        runs.append((c.name, seed, out.name, tuple(extra)))
        if seed == 7:
            return "fastdet adapt: error: refused"
        shutil.copy(DEFAULT_MODEL_PATH, out)  # a model file where adapt would write one
        return None

    lines = study([clip], [0, 7, 3], tmp_path, data, ["--every", "2"], run=fake_adapt)
    assert runs == [("boston_street", s, f"boston_street.s{s}.npz", ("--every", "2")) for s in (0, 7, 3)]
    captured = capsys.readouterr()
    assert "boston_street seed 7: adapt: fastdet adapt: error: refused" in captured.err
    assert lines[0] == "| clip | seed 0 | seed 7 | seed 3 | mean | lowest | highest |"
    # the slow, obvious twin: the eval command on the same model file
    assert cli.main(["eval", "--gt", str(clip.gt_path), "--video", str(clip.video), "--model",
                     str(tmp_path / "boston_street.s0.npz"), "--json"]) == 0
    want = json.loads(capsys.readouterr().out)
    cell = f"{want['f1']:.3f} ({want['tp']} / {want['fp']} / {want['fn']})"
    # seed 7 refused: two cells, then mean, lowest, highest of the two (equal models: equal figures)
    f1 = f"{want['f1']:.3f}"
    assert lines[-1] == f"| boston_street | {cell} | {cell} | **{f1}** | {f1} | {f1} |"
    assert want["tp"] > 0


def test_row_mean_lowest_highest_and_no_score():
    got = row("c", [SeedScore(0, 0.5, 5, 5, 5), SeedScore(1, 0.7, 7, 3, 3), SeedScore(2, 0.6, 6, 4, 4)])
    assert got == "| c | 0.500 (5 / 5 / 5) | 0.700 (7 / 3 / 3) | 0.600 (6 / 4 / 4) | **0.600** | 0.500 | 0.700 |"
    assert row("c", []) == "| c | n/a | n/a | n/a |"


def test_adapt_clip_keeps_an_existing_model_and_reports_a_refusal(data, tmp_path):
    clip = {c.name: c for c in annotated_clips(data)}["boston_street"]
    there = tmp_path / "there.npz"
    there.write_bytes(b"x")
    assert adapt_clip(clip, 0, there, tmp_path) is None  # not run: the file is there
    # no teachers/yolox_nano.onnx under this data folder: adapt's one line, nothing written
    err = adapt_clip(clip, 0, tmp_path / "new.npz", tmp_path)
    assert err is not None and "yolox_nano.onnx" in err
    assert not (tmp_path / "new.npz").exists()


@pytest.mark.parametrize("argv, message", [(["--clips", "nope"], "no annotated clip nope"),
                                           (["--seeds", "1,x"], "--seeds")])
def test_bad_arguments_are_one_line(data, tmp_path, capsys, argv, message):
    from tools.studies.adapt_seeds import main

    with pytest.raises(SystemExit) as e:
        main(["--work", str(tmp_path / "w"), *argv])
    assert e.value.code == 2 and message in capsys.readouterr().err

"""tools/scripts/rebuild_models.py: its steps are the commands the shipped models record (a model
retrained another way, or a step changed without retraining, fails here), each step reads only
files that earlier steps built, and a failing step is one line, exit 1, no file left behind."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from tools.scripts import rebuild_models as rb

ONCOMING_SH = rb.ROOT / "tools" / "scripts" / "oncoming_model.sh"


def recorded(step: rb.Step) -> str:
    """The command the shipped file of ``step`` records."""
    _, meta = rb.read_model_file(rb.PACKAGE_MODELS / step.file)
    return meta["command"] if "command" in meta else meta["training"]["command"]


def oncoming_final_train(work: str, out: str) -> str:
    """The last ``fastdet train`` of oncoming_model.sh (the one whose command oncoming.npz records),
    its shell variables filled in as the script fills them."""
    text = ONCOMING_SH.read_text()
    t = re.search(r'^T="([^"]*)"$', text, re.M)
    negs = re.findall(r"^negatives (.*)$", text, re.M)
    train = [ln for ln in text.splitlines() if ln.startswith("python -m fastdet train")]
    assert t and negs and train, "oncoming_model.sh no longer has the shape this test reads"
    opts = t.group(1).replace("${ONCOMING_TRAIN_ARGS:-}", "").strip()
    neg = " ".join(f"--negatives {d}" for d in negs[-1].split())
    line = train[-1].replace("$T", opts).replace('"${NEG[@]}"', neg)
    return line.replace('"$W"', work).replace('"$OUT"', out).replace('"', "")


def test_each_step_is_the_command_its_shipped_model_records(tmp_path):
    commands = rb.step_commands(tmp_path, tmp_path / "work")
    for step in rb.STEPS:
        mine = commands[step.name]
        if step.name == "oncoming":
            assert mine[:2] == ["bash", "tools/scripts/oncoming_model.sh"]
            made = oncoming_final_train(mine[2], mine[3])
        else:
            made = " ".join(mine)
        assert rb.canonical(recorded(step)) == rb.canonical(made), step.name


def test_canonical_tells_recipes_apart():
    base = "python -m fastdet train --out a.npz --seed 0 --C 0.0218 --no-progress"
    assert rb.canonical(base) == rb.canonical("/usr/bin/python3 -m fastdet train --C 0.0218 --seed 0 --out /x/b.npz")
    assert rb.canonical(base) != rb.canonical(base.replace("0.0218", "0.03"))
    assert rb.canonical(base) != rb.canonical(base + " --reencode 0.25")
    assert rb.canonical("python -m tools.refine_eval --clips x") == rb.canonical(
        "python -m tools.studies.refine_eval --clips x --cache /tmp/c")
    assert rb.canonical("python -m fastdet train --negatives /a/neg0") != rb.canonical(
        "python -m fastdet train --negatives /a/neg1")


def test_steps_read_only_the_files_earlier_steps_built(tmp_path):
    commands = rb.step_commands(tmp_path, tmp_path / "work")
    built: set[str] = set()
    for step in rb.STEPS:
        read = {Path(w).name for w in commands[step.name]
                if w.startswith(str(tmp_path)) and w.endswith(".npz") and Path(w).parent == tmp_path
                and not w.endswith(".partial.npz")}
        assert read == set(step.needs) <= built, step.name
        assert str(rb.partial(tmp_path / step.file)) in commands[step.name], step.name
        assert not any(str(rb.PACKAGE_MODELS) in w for w in commands[step.name]), step.name
        built.add(step.file)
    assert built == {p.name for p in rb.PACKAGE_MODELS.glob("*.npz")}


def _fake_steps(monkeypatch, template: Path, fail: str | None) -> None:
    """Each step copies a small model file to its partial name (``fail``: that one, then exits 3)."""
    def commands(out: Path, work: Path) -> dict[str, list[str]]:
        return {s.name: ["sh", "-c", f'cp "$0" "$1"; exit {3 if s.name == fail else 0}', str(template),
                         str(rb.partial(out / s.file))] for s in rb.STEPS}
    monkeypatch.setattr(rb, "step_commands", commands)


def test_a_failing_step_is_one_line_and_leaves_no_file(tmp_path, monkeypatch, capsys):
    template = tmp_path / "template.npz"
    np.savez(template, coef=np.zeros(3), metadata=np.frombuffer(b"{}", np.uint8))
    out_dir = tmp_path / "out"
    _fake_steps(monkeypatch, template, fail="refine_cameras")
    assert rb.main(["--out", str(out_dir)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "step refine_cameras failed (exit status 3)" in err[0]
    assert sorted(p.name for p in out_dir.glob("*.npz")) == ["default.npz", "oncoming.npz"]
    # --from reuses them and runs the rest
    _fake_steps(monkeypatch, template, fail=None)
    assert rb.main(["--out", str(out_dir), "--from", "refine_cameras"]) == 0
    out = capsys.readouterr().out
    assert "[3/5] refine_cameras: wrote" in out and "[1/5]" not in out
    assert sorted(p.name for p in out_dir.glob("*.npz")) == sorted(s.file for s in rb.STEPS)
    assert "compare verifier.npz: arrays differ (coef max |diff| n/a (shapes differ)" in out


def test_from_needs_the_earlier_files_and_out_stays_outside_the_package(tmp_path, capsys):
    assert rb.main(["--out", str(tmp_path), "--from", "verifier"]) == 2
    assert "default.npz" in capsys.readouterr().err
    assert rb.main(["--out", str(rb.PACKAGE_MODELS)]) == 2
    assert "inside the package" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_compare_reports_the_largest_difference(tmp_path):
    meta = np.frombuffer(b'{"a": 1, "b": {"c": 2}}', np.uint8)
    np.savez(tmp_path / "x.npz", coef=np.array([1.0, 2.0]), metadata=meta)
    np.savez(tmp_path / "y.npz", coef=np.array([1.0, 2.5]),
             metadata=np.frombuffer(b'{"a": 1, "b": {"c": 3}, "d": 0}', np.uint8))
    c = rb.compare(tmp_path / "x.npz", tmp_path / "y.npz")
    assert c["arrays"]["coef"]["max_abs_diff"] == pytest.approx(0.5) and not c["identical_arrays"]
    assert c["metadata_differs"] == ["b.c"] and c["metadata_only_old"] == ["d"]
    assert rb.compare(tmp_path / "x.npz", tmp_path / "x.npz")["identical_arrays"]

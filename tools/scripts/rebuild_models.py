"""Rebuild the five bundled model files (``fastdet/models/``) from the data folder, in order, into
a folder of their own (docs/training.md "Rebuilding every bundled model").

Each step is the command that made the file (the one its metadata records, ``command``), pointed
at the files the steps before it built in the same folder, never at the package's:

1. ``default.npz``, the main model: ``python -m fastdet train`` (crops only);
2. ``oncoming.npz``, the wide-window model: ``tools/scripts/oncoming_model.sh`` (its mining rounds
   search the wide model beside the main model of step 1);
3. ``refine_cameras.npz``, the default box regressor: ``tools.studies.refine_loo --ship`` (fitted
   on the pipeline's own boxes too: the pipeline of steps 1 and 2, unrefined);
4. ``refine.npz``, the Udacity box regressor: ``tools.studies.refine_eval --ship`` (its fit needs
   no model; its held-out figures are those of the unrefined pipeline of steps 1 and 2);
5. ``verifier.npz``, the picture search's box verifier: ``tools.scripts.verifier_model`` (its
   first stage is the picture search with the models of steps 1 and 3).

Usage (from the repository root)::

    python -m tools.scripts.rebuild_models [--out DIR] [--from STEP] [--data DIR] [--dry-run]
        [--into-package]

``--out`` (default ``$TMPDIR/fastdet-rebuild``) gets the five files, ``work/`` (the steps'
caches and crops) and ``logs/`` (each step's output). A step writes ``NAME.partial.npz`` and
the file is renamed to ``NAME.npz`` only when the step succeeded; on a failure the run stops
with one line (the step, its exit status, its log) and exit status 1. ``--from STEP`` starts
at that step, reusing the files of the steps before it in ``--out``. ``--into-package`` copies
the five files into ``fastdet/models/`` once all five are built (never a part of them). At the
end every file is compared with the package's (same arrays? largest difference; metadata keys
that differ).

Why Python and not a shell script: the steps are data (:data:`STEPS`, :func:`step_commands`)
that ``tests/tools/scripts/test_rebuild_models.py`` holds against the commands recorded in the
shipped models, and the comparison reads the model files.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: the repository root (the steps run there: the shell step reads tools/test_images.gt.txt)
ROOT = Path(__file__).resolve().parents[2]
#: the package's model folder
PACKAGE_MODELS = ROOT / "fastdet" / "models"


@dataclass(frozen=True)
class Step:
    """One model file and what it is built from: ``needs``, the files of earlier steps."""

    name: str
    file: str
    needs: tuple[str, ...]


#: the steps in the order they run (each one's ``needs`` are built before it)
STEPS = (
    Step("default", "default.npz", ()),
    Step("oncoming", "oncoming.npz", ("default.npz",)),
    Step("refine_cameras", "refine_cameras.npz", ("default.npz", "oncoming.npz")),
    Step("refine", "refine.npz", ("default.npz", "oncoming.npz")),
    Step("verifier", "verifier.npz", ("default.npz", "refine_cameras.npz")),
)

#: the main model's recipe (docs/training.md "The main model")
DEFAULT_ARGS = ("--seed", "0", "--truncate", "0.25", "--truncate-keep", "0.75", "0.875", "--reencode", "0.25",
                "--C", "0.0218")
#: the default box regressor's recipe (docs/geometry.md "A regressor fitted on the pipeline's own boxes")
REFINE_CAMERAS_ARGS = ("--inputs", "both", "--own-repeat", "8", "--refine", "iterations=3")
#: the Udacity box regressor's held-out measurement (docs/geometry.md; fitted on test_video + test images)
REFINE_ARGS = ("--clips", "test_small1", "--variants", "original")


#: options that name where a step reads or writes a file or keeps a cache, or how it reports
#: (not what the model is): left out when a recorded command is compared with a step's
INCIDENTAL = frozenset({"--out", "--ship", "--cache", "--out-dir", "--json", "--model", "--oncoming-model",
                        "--wide-model", "--refine-model", "--no-progress", "--into-package", "--reuse"})
#: modules that moved since a bundled file was made: their old name, the name today
MOVED = {"tools.refine_eval": "tools.studies.refine_eval"}


def canonical(command: str | list[str]) -> tuple[str, tuple[tuple[str, ...], ...]]:
    """A command as ``(program, options)`` to compare what it makes: the module run (and the
    ``fastdet`` subcommand), its options sorted, each with its values, :data:`INCIDENTAL` ones
    left out, a value that is a path reduced to its last part (``/tmp/w/neg0`` -> ``neg0``)."""
    words = shlex.split(command) if isinstance(command, str) else list(command)
    if words and (Path(words[0]).name.startswith("python") or words[0] == sys.executable):
        words = words[1:]
    if words[:1] == ["-m"]:
        words = words[1:]
    program = MOVED.get(words[0], words[0]) if words else ""
    rest = words[1:]
    if program == "fastdet" and rest and not rest[0].startswith("-"):
        program, rest = f"fastdet {rest[0]}", rest[1:]
    options: list[tuple[str, ...]] = []
    for w in rest:
        if w.startswith("--") or not options:
            options.append((w,))
        else:
            options[-1] += (Path(w).name if "/" in w else w,)
    return program, tuple(sorted(o for o in options if o[0] not in INCIDENTAL))


def partial(path: Path) -> Path:
    """The name a step writes ``path`` under until it has succeeded (``NAME.partial.npz``)."""
    return path.with_name(path.stem + ".partial" + path.suffix)


def step_commands(out: Path, work: Path) -> dict[str, list[str]]:
    """Each step's command (argv), writing its file's :func:`partial` name in ``out`` and reading
    the earlier steps' files from ``out``; caches and crops in ``work``."""
    m = {s.name: out / s.file for s in STEPS}
    py = [sys.executable, "-m"]
    return {
        "default": py + ["fastdet", "train", "--out", str(partial(m["default"])), *DEFAULT_ARGS, "--no-progress"],
        "oncoming": ["bash", "tools/scripts/oncoming_model.sh", str(work / "oncoming"),
                     str(partial(m["oncoming"])), str(m["default"])],
        "refine_cameras": py + ["tools.studies.refine_loo", "--out-dir", str(work / "refine_loo"),
                                *REFINE_CAMERAS_ARGS, "--model", str(m["default"]),
                                "--oncoming-model", str(m["oncoming"]), "--ship", str(partial(m["refine_cameras"]))],
        "refine": py + ["tools.studies.refine_eval", *REFINE_ARGS, "--model", str(m["default"]),
                        "--oncoming-model", str(m["oncoming"]), "--cache", str(work / "refine_eval"),
                        "--ship", str(partial(m["refine"]))],
        "verifier": py + ["tools.scripts.verifier_model", "--model", str(m["default"]),
                          "--refine-model", str(m["refine_cameras"]), "--cache",
                          str(work / "verifier_first_stage.npz"), "--out", str(partial(m["verifier"])),
                          "--no-progress"],
    }


# ---------------------------------------------------------------------------------------- comparison


def read_model_file(path: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(arrays, metadata)`` of a model file (plain arrays, ``metadata`` UTF-8 JSON)."""
    import numpy as np

    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k != "metadata"}
        meta = json.loads(z["metadata"].tobytes().decode("utf-8")) if "metadata" in z.files else {}
    return arrays, meta


def _flat(d: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(d, dict):
        out: dict[str, Any] = {}
        for k, v in d.items():
            out.update(_flat(v, f"{prefix}.{k}" if prefix else str(k)))
        return out
    return {prefix: d}


def compare(new: Path, old: Path) -> dict[str, Any]:
    """How the model file ``new`` differs from ``old``: per array ``equal`` and the largest
    absolute difference (``None`` when the shapes differ), and the metadata entries (dotted
    keys) that differ, are only in ``new`` or only in ``old``."""
    import numpy as np

    a, ma = read_model_file(new)
    b, mb = read_model_file(old)
    arrays: dict[str, Any] = {}
    for k in sorted(set(a) | set(b)):
        if k not in a or k not in b or a[k].shape != b[k].shape:
            arrays[k] = {"equal": False, "max_abs_diff": None}
        else:
            diff = np.abs(a[k].astype(np.float64) - b[k].astype(np.float64))
            arrays[k] = {"equal": bool(np.array_equal(a[k], b[k])),
                         "max_abs_diff": float(diff.max()) if diff.size else 0.0,
                         "max_abs": float(np.abs(b[k]).max()) if b[k].size else 0.0}
    fa, fb = _flat(ma), _flat(mb)
    return {"arrays": arrays, "identical_arrays": all(v["equal"] for v in arrays.values()),
            "metadata_differs": sorted(k for k in set(fa) & set(fb) if fa[k] != fb[k]),
            "metadata_only_new": sorted(set(fa) - set(fb)), "metadata_only_old": sorted(set(fb) - set(fa))}


def print_comparison(out: Path, against: Path) -> None:
    for s in STEPS:
        new, old = out / s.file, against / s.file
        if not (new.is_file() and old.is_file()):
            continue
        c = compare(new, old)
        arr = ", ".join(f"{k} {'equal' if v['equal'] else 'max |diff| %s' % _g(v['max_abs_diff'])}"
                        for k, v in c["arrays"].items())
        verdict = "same arrays" if c["identical_arrays"] else "arrays differ"
        print(f"compare {s.file}: {verdict} ({arr}); metadata differs in {c['metadata_differs'] or 'nothing'}"
              + (f", only rebuilt {c['metadata_only_new']}" if c["metadata_only_new"] else "")
              + (f", only shipped {c['metadata_only_old']}" if c["metadata_only_old"] else ""), flush=True)


def _g(v: float | None) -> str:
    return "n/a (shapes differ)" if v is None else f"{v:.3g}"


# ---------------------------------------------------------------------------------------- running


def run_step(step: Step, argv: list[str], log: Path, env: dict[str, str]) -> int:
    """Run one step's command in the repository root, its output into ``log``; its exit status
    (the child's process group is stopped on Ctrl-C, then the interrupt goes on)."""
    with open(log, "w") as f:
        f.write("$ " + shlex.join(argv) + "\n")
        f.flush()
        proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            return proc.wait()
        except BaseException:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait()
            raise


def _inside(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def install(out: Path) -> None:
    """Copy the five files of ``out`` into the package (each via a temporary name and a rename)."""
    for s in STEPS:
        dst = PACKAGE_MODELS / s.file
        tmp = partial(dst)
        shutil.copyfile(out / s.file, tmp)
        os.replace(tmp, dst)
        print(f"installed {dst}", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path(tempfile.gettempdir()) / "fastdet-rebuild",
                    help="folder of the rebuilt files, work/ and logs/ (default: $TMPDIR/fastdet-rebuild)")
    ap.add_argument("--from", dest="start", choices=[s.name for s in STEPS], default=STEPS[0].name,
                    help="first step to run; the earlier steps' files must be in --out already")
    ap.add_argument("--data", type=Path, default=None, help="data folder (default: $FASTDET_DATA or ../shared/data)")
    ap.add_argument("--into-package", action="store_true",
                    help="once all five are built, copy them into fastdet/models/ (replacing the bundled files)")
    ap.add_argument("--dry-run", action="store_true", help="print each step's command and stop")
    a = ap.parse_args(argv)
    out = a.out.absolute()
    if _inside(out, PACKAGE_MODELS.parent):
        print(f"rebuild_models: --out {out} is inside the package; build elsewhere and give --into-package",
              file=sys.stderr)
        return 2
    work, logs = out / "work", out / "logs"
    commands = step_commands(out, work)
    first = [s.name for s in STEPS].index(a.start)
    todo = STEPS[first:]
    if a.dry_run:
        for s in todo:
            print(f"{s.name}: {shlex.join(commands[s.name])}")
        return 0
    missing = [str(out / f) for s in todo for f in s.needs
               if f not in {t.file for t in todo} and not (out / f).is_file()]
    if missing:
        print(f"rebuild_models: --from {a.start} needs {', '.join(sorted(set(missing)))} (built by an earlier step)",
              file=sys.stderr)
        return 2
    for d in (out, work, logs):
        d.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    env["PYTHONUNBUFFERED"] = "1"  # each step's log as it goes
    if a.data is not None:
        env["FASTDET_DATA"] = str(a.data.absolute())
    previous = signal.signal(signal.SIGTERM, _interrupt)  # a kill stops the step, leaves no partial file
    try:
        return _run(a, out, work, logs, commands, first, env)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(a: argparse.Namespace, out: Path, work: Path, logs: Path, commands: dict[str, list[str]], first: int,
         env: dict[str, str]) -> int:
    """The steps from ``STEPS[first]`` on (:func:`main`)."""
    todo = STEPS[first:]
    threads = env.get("NUMBA_NUM_THREADS") or str(os.cpu_count())
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"rebuild_models: {len(todo)} steps into {out} (threads {threads}, load {load})", flush=True)
    for s in todo:  # no file of an earlier run beside this run's, should this one stop half-way
        (out / s.file).unlink(missing_ok=True)
    times: dict[str, float] = {}
    t_all = time.perf_counter()
    for i, s in enumerate(todo, first + 1):
        final = out / s.file
        tmp = partial(final)
        tmp.unlink(missing_ok=True)
        log = logs / f"{s.name}.log"
        print(f"[{i}/{len(STEPS)}] {s.name}: {shlex.join(commands[s.name])}", flush=True)
        t0 = time.perf_counter()
        try:
            rc = run_step(s, commands[s.name], log, env)
        except KeyboardInterrupt:
            tmp.unlink(missing_ok=True)
            print(f"rebuild_models: interrupted in step {s.name}; {s.file} not written", file=sys.stderr)
            return 130
        dt = time.perf_counter() - t0
        if rc != 0 or not tmp.is_file():
            tmp.unlink(missing_ok=True)
            why = f"exit status {rc}" if rc != 0 else f"exit status 0 but no {tmp.name}"
            print(f"rebuild_models: step {s.name} failed ({why}) after {dt:.0f} s; {s.file} not written; "
                  f"its output: {log}", file=sys.stderr)
            return 1
        os.replace(tmp, final)
        times[s.name] = dt
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"[{i}/{len(STEPS)}] {s.name}: wrote {final} in {dt:.0f} s (load {load})", flush=True)
    total = time.perf_counter() - t_all
    print("rebuild_models: " + ", ".join(f"{k} {v:.0f} s" for k, v in times.items()) + f"; total {total:.0f} s",
          flush=True)
    print_comparison(out, PACKAGE_MODELS)
    if a.into_package:
        install(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())

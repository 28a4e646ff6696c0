"""The command dispatcher (fastdet.cli.main): which errors become one line, which show a
traceback, the exit statuses, and that only the chosen command's module is imported."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import types
from pathlib import Path

import pytest

import fastdet
from fastdet.cli.main import SUBCOMMANDS, build_parser, main
from fastdet.errors import DataError, FastdetError, ModelError

REPO = Path(__file__).resolve().parents[2]


def _python(code: str, **env) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter from the project root."""
    full_env = {k: v for k, v in os.environ.items() if k != "FASTDET_DEBUG"}
    full_env.update(PYTHONPATH=str(REPO), **env)
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          env=full_env, cwd=REPO, timeout=120)


@pytest.fixture
def fake_command(monkeypatch):
    """A command ``fake`` whose run() does what the test sets in ``box['run']``."""
    box = {}
    mod = types.ModuleType("fake_fastdet_command")
    mod.add_arguments = lambda p: p.add_argument("--n", type=int, default=1)
    mod.run = lambda args: box["run"](args)
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setitem(SUBCOMMANDS, "fake", (mod.__name__, "a command for the tests"))
    monkeypatch.delenv("FASTDET_DEBUG", raising=False)
    return box


def _raise(exc):
    def run(args):
        raise exc
    return run


def test_run_status_and_arguments(fake_command):
    seen = {}
    fake_command["run"] = lambda args: seen.update(n=args.n) or 3
    assert main(["fake", "--n", "7"]) == 3 and seen == {"n": 7}
    fake_command["run"] = lambda args: None
    assert main(["fake"]) == 0


@pytest.mark.parametrize("exc", [FastdetError("the input is bad"), DataError("x.mp4: not a video"),
                                 ModelError("m.npz: not a model")])
def test_fastdet_errors_are_one_line_and_exit_2(fake_command, capsys, exc):
    fake_command["run"] = _raise(exc)
    assert main(["fake"]) == 2
    err = capsys.readouterr().err
    assert err == f"fastdet fake: error: {exc}\n"


def test_fastdet_debug_shows_the_traceback_of_user_errors(fake_command, monkeypatch):
    fake_command["run"] = _raise(DataError("bad"))
    monkeypatch.setenv("FASTDET_DEBUG", "1")
    with pytest.raises(DataError, match="bad"):
        main(["fake"])
    monkeypatch.setenv("FASTDET_DEBUG", "0")
    assert main(["fake"]) == 2


@pytest.mark.parametrize("exc", [RuntimeError("a bug"), ValueError("a bug"), OSError(5, "a bug"),
                                 ZeroDivisionError("a bug"), AssertionError("a bug")])
def test_other_exceptions_are_bugs_and_propagate(fake_command, capsys, exc):
    fake_command["run"] = _raise(exc)
    with pytest.raises(type(exc)):
        main(["fake"])
    assert "error:" not in capsys.readouterr().err


def test_ctrl_c_exits_130_with_one_line(fake_command, capsys):
    def run(args):
        os.kill(os.getpid(), signal.SIGINT)  # a real Ctrl-C, delivered to the main thread
        signal.pause() if hasattr(signal, "pause") else None
        raise AssertionError("the signal did not stop the command")

    fake_command["run"] = run
    # pytest started with SIGINT ignored (`pytest &` in a script, nohup): the command keeps an
    # inherited SIG_IGN (tests/test_signals.py), so this Ctrl-C would be ignored and pause() wait
    # for ever; the test gives the process Python's own handler, as an interactive start has
    inherited = signal.getsignal(signal.SIGINT)
    if inherited is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        before = signal.getsignal(signal.SIGINT)
        assert main(["fake"]) == 130
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("fastdet fake: interrupted"), err
        assert signal.getsignal(signal.SIGINT) is before  # the test runner's handler is back
    finally:
        signal.signal(signal.SIGINT, inherited)


def test_no_command_prints_help(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    assert "usage:" in out and all(name in out for name in SUBCOMMANDS)


def test_unknown_command_and_bad_arguments_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["no-such-command"])
    assert exc.value.code == 2 and "invalid choice" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["image", "in.jpg", "-o", "out.jpg", "--no-such-option"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--no-such-option" in err and "image" in err


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.strip() == f"fastdet {fastdet.__version__}"


def test_every_command_has_help():
    parser = build_parser()  # every command's arguments
    for name in SUBCOMMANDS:
        with pytest.raises(SystemExit) as exc:
            parser.parse_args([name, "--help"])
        assert exc.value.code == 0


# --------------------------------------------------------------------------- real processes


def test_real_process_user_error_bug_and_interrupt():
    """In a fresh interpreter: a FastdetError gives one line and status 2, a bug a
    traceback and status 1, a SIGINT status 130."""
    code = """
        import os, signal, sys, types
        from fastdet.cli.main import SUBCOMMANDS, main
        from fastdet.errors import DataError
        mod = types.ModuleType("fake_cmd")
        mod.add_arguments = lambda p: None
        def run(args):
            kind = os.environ["KIND"]
            if kind == "user":
                raise DataError("in.mp4: not a video")
            if kind == "bug":
                return 1 // 0
            os.kill(os.getpid(), signal.SIGINT)
            signal.pause()
        mod.run = run
        sys.modules["fake_cmd"] = mod
        SUBCOMMANDS["fake"] = ("fake_cmd", "test")
        sys.exit(main(["fake"]))
    """
    r = _python(code, KIND="user")
    assert (r.returncode, r.stderr) == (2, "fastdet fake: error: in.mp4: not a video\n")
    r = _python(code, KIND="bug")
    assert r.returncode == 1 and "Traceback" in r.stderr and "ZeroDivisionError" in r.stderr
    r = _python(code, KIND="interrupt")
    assert r.returncode == 130 and r.stderr.startswith("fastdet fake: interrupted") and "Traceback" not in r.stderr


#: a fresh interpreter imports the dispatcher, then runs each command's ``--help`` in a forked
#: child of its own (each child starts from that interpreter: nothing a command imports is seen
#: by another; the children run side by side, on every core) and prints the modules loaded
#: then, one JSON line a command
_IMPORTED = """
    import json, os, sys, tempfile
    from fastdet.cli.main import main
    out = tempfile.mkdtemp()
    pids = {{}}
    for name in {names!r}:
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            code = 0
            try:
                sys.stdout = open(os.devnull, "w")  # the help text
                try:
                    main([name, "--help"])
                except SystemExit:
                    pass
                with open(os.path.join(out, name + ".json"), "w") as f:
                    json.dump([name, sorted(sys.modules)], f)
            except BaseException:
                import traceback
                traceback.print_exc()
                code = 1
            os._exit(code)
        pids[name] = pid
    for name, pid in pids.items():
        _, status = os.waitpid(pid, 0)
        assert os.waitstatus_to_exitcode(status) == 0, name
        with open(os.path.join(out, name + ".json")) as f:
            print(f.read(), flush=True)
"""

_TEST_IMPORTS = "test_only_the_chosen_command_module_is_imported"


@pytest.fixture(scope="module")
def modules_after_help(request) -> dict[str, set[str]]:
    """Command -> the modules loaded after its ``--help``, for the commands this run tests (one
    interpreter's start-up for all of them, not one each)."""
    names = [item.callspec.params["name"] for item in request.session.items
             if getattr(item, "originalname", None) == _TEST_IMPORTS and item.module is request.module]
    r = _python(_IMPORTED.format(names=names))
    assert r.returncode == 0, r.stderr
    found = dict(json.loads(line) for line in r.stdout.splitlines() if line.startswith("["))
    return {name: set(mods) for name, mods in found.items()}


@pytest.mark.parametrize("name", [pytest.param(n, marks=() if n == "video" else pytest.mark.slow)
                                  for n in SUBCOMMANDS])
def test_only_the_chosen_command_module_is_imported(name, modules_after_help):
    mods = modules_after_help[name]
    commands = {m for m, _ in SUBCOMMANDS.values()}
    assert commands & mods == {SUBCOMMANDS[name][0]}
    if name in ("video", "image"):  # the detection commands do not pay for training or clusters
        assert not {"sklearn", "dask", "distributed"} & mods


def test_nothing_outside_cli_imports_cli():
    """``import fastdet`` and its public names do not load the CLI."""
    r = _python("""
        import json, sys
        import fastdet
        for name in fastdet.__all__:
            getattr(fastdet, name)
        print(json.dumps(sorted(m for m in sys.modules if m.startswith("fastdet"))))
    """)
    assert r.returncode == 0, r.stderr
    mods = json.loads(r.stdout.strip().splitlines()[-1])
    assert "fastdet.video" in mods and not [m for m in mods if m.startswith("fastdet.cli")]


def test_results_to_a_full_standard_output_are_one_line(tmp_path):
    """``fastdet eval ... > /dev/full``: one line and exit 2, not an OSError traceback."""
    import subprocess
    import sys
    gt, pred = tmp_path / "g.txt", tmp_path / "p.txt"
    gt.write_text("1,1,10,10,40,30\n")
    pred.write_text("1,1,10,10,40,30,0.9\n")
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "fastdet", "eval", "--gt", str(gt), "--pred", str(pred)],
                           stdout=full, stderr=subprocess.PIPE, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().splitlines() == [
        "fastdet eval: error: cannot write the results to standard output (No space left on device); "
        "the output files, if any, are complete"]


@pytest.mark.parametrize("value", ["0", "-1", "two"])
def test_bad_numba_thread_count_is_one_line(value, capsys, monkeypatch):
    monkeypatch.setenv("NUMBA_NUM_THREADS", value)
    assert main(["image", "in.jpg", "-o", "out.jpg"]) == 2
    assert capsys.readouterr().err.strip() == (
        f"fastdet image: error: NUMBA_NUM_THREADS must be a whole number >= 1, got {value!r}")


@pytest.fixture
def help_of(capsys, monkeypatch):
    """``fastdet COMMAND --help`` on an 80-column terminal (argparse reads $COLUMNS), in this
    process: the text is the same as a fresh interpreter's (the program name too)."""
    monkeypatch.setenv("COLUMNS", "80")

    def run(command: str) -> list[str]:
        capsys.readouterr()
        with pytest.raises(SystemExit) as exc:
            main([command, "--help"])
        assert exc.value.code == 0
        return capsys.readouterr().out.splitlines()

    return run


def test_video_help_fits_a_screen_in_groups(help_of):
    """Issue 33, item 6: ``video --help`` was 122 lines; grouped, one line an option, aliases hidden."""
    lines = help_of("video")
    assert len(lines) <= 55, len(lines)
    assert max(map(len, lines)) <= 80
    for title in ("inputs and outputs:", "models and search:", "tracking:", "advanced:"):
        assert title in lines
    text = "\n".join(lines)
    for hidden in ("--own-vehicle ", "--split-neighbours", "kept for scripts"):
        assert hidden not in text.replace("--no-own-vehicle", "").replace("--no-split-neighbours", "")


@pytest.mark.parametrize("command", ["eval", "train", "bench", "batch"])
def test_long_helps_are_grouped(command, help_of):
    lines = help_of(command)
    assert len(lines) <= 50 and max(map(len, lines)) <= 80, (len(lines), max(map(len, lines)))


def test_hidden_aliases_are_still_accepted(help_of):
    from fastdet.cli.main import build_parser

    p = build_parser("video")
    a = p.parse_args(["video", "x.mp4", "--own-vehicle", "--split-neighbours"])
    assert a.own_vehicle and a.split_neighbours
    p = build_parser("mine-negatives")
    a = p.parse_args(["mine-negatives", "x.mp4", "--out", "d", "--wide-model", "w.npz", "--part", "wide"])
    assert str(a.oncoming_model) == "w.npz" and a.part == "wide"
    text = "\n".join(help_of("mine-negatives"))
    assert "--wide-model" not in text and "oncoming,wide" not in text and "former name" not in text


class _ClosedPipe:
    """A standard output whose reader is gone."""

    def write(self, text):
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self):
        raise BrokenPipeError(32, "Broken pipe")


def test_a_closed_standard_output_ends_quietly_with_141(fake_command, capsys, monkeypatch):
    """Issue 34 (18): ``... | true`` was a BrokenPipeError traceback."""
    fake_command["run"] = lambda args: print("results") or 0
    monkeypatch.setattr(sys, "stdout", _ClosedPipe())
    assert main(["fake"]) == 141
    assert capsys.readouterr().err == ""


def test_eval_into_a_closed_pipe_is_quiet(tmp_path):
    """``fastdet eval ... | true`` in a real process: exit 141, nothing on stderr."""
    gt, pred = tmp_path / "g.txt", tmp_path / "p.txt"
    gt.write_text("1,1,10,10,40,30\n")
    pred.write_text("1,1,10,10,40,30,0.9\n")
    env = {k: v for k, v in os.environ.items() if k != "FASTDET_DEBUG"}
    p = subprocess.Popen([sys.executable, "-m", "fastdet", "eval", "--gt", str(gt), "--pred", str(pred)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    p.stdout.close()  # the reader is gone before the results are printed
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 141 and err == "", err

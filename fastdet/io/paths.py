"""Every command's files, checked together before any work: :func:`check_paths`.

A command names its inputs (the video, model files, ground truth, predictions) and its
outputs (video, box files, summary, plot, model, table). Each is resolved to its real path
(symlinks followed, ``..`` removed) and, where the file exists, compared by device and
inode as well (a hard link is the same file under another name). Refused in one line
(:class:`~fastdet.errors.DataError`), before anything is read or written:

- an output that is one of the inputs (``eval --plot gt.txt``, ``video --boxes model.npz``);
- two outputs that are one file (``-o x.mp4 --summary x.mp4``);
- an output that is a folder, whose folder does not exist or cannot be written to;
- an output inside the installed ``fastdet`` package (:data:`PACKAGE_DIR`, real paths: a symlink
  into it counts), unless the command was told so with ``--into-package`` (``train``, for the
  scripts that rebuild a bundled model): every later run would use what it wrote
  (:func:`check_outside_package`; folder outputs: :func:`check_output_folder`).

Inputs that are not files (a URL, a camera index) take no part; an output that is a frame
of an input image sequence (``img%04d.jpg`` and ``--boxes img0003.jpg``, existing or not) is
refused (:func:`is_sequence_frame`). Whether a name is a sequence is what OpenCV makes of it
(:func:`~fastdet.io.reader.is_image_sequence`: a file literally named ``a%d.mp4`` is that
file, an input like any other). The bundled model files are inputs of every command that loads a model
(:func:`bundled_models`).
"""
from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from ..errors import DataError
from .atomic import folder_writable, partial_name

#: the installed package's folder, real path (``Path(fastdet.__file__).parent``, symlinks resolved)
PACKAGE_DIR = Path(__file__).resolve().parent.parent
#: the folder of the model files shipped with fastdet
MODELS_DIR = PACKAGE_DIR / "models"
#: the option that lets a command write into :data:`PACKAGE_DIR`
INTO_PACKAGE_FLAG = "--into-package"

Named = tuple[str, "str | os.PathLike[str] | None"]


def bundled_models() -> list[Named]:
    """The shipped model files, as ``(label, path)`` inputs."""
    return [("the bundled model", p) for p in sorted(MODELS_DIR.glob("*.npz"))]


def _stat_key(path: str) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _same(a: str, b: str) -> bool:
    """``a`` and ``b`` name one file: the same real path, or the same existing inode."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    ka, kb = _stat_key(a), _stat_key(b)
    return ka is not None and ka == kb


def _is_file_input(path: str) -> bool:
    """A path that names (or would name) a file: not a URL, camera index or image sequence."""
    from .reader import source_kind  # the reader imports OpenCV: only when checking

    return source_kind(path) == "file"


def _is_sequence(path: str) -> bool:
    from .reader import source_kind

    return source_kind(path) == "sequence"


def is_sequence_frame(path: str | os.PathLike[str], pattern: str | os.PathLike[str]) -> bool:
    """``path`` names a frame of the image sequence ``pattern`` (``img%04d.jpg``): it lies in the
    pattern's folder (real paths, a symlink followed) and its name is one the pattern gives,
    whether that frame exists or not."""
    from .reader import sequence_regex

    rx = sequence_regex(os.fspath(pattern))
    if rx is None:
        return False
    folder = os.path.realpath(os.path.dirname(os.path.abspath(os.fspath(pattern))))
    name = os.fspath(path)
    beside = os.path.join(os.path.realpath(os.path.dirname(os.path.abspath(name))), os.path.basename(name))
    for p in (os.path.realpath(name), beside):
        if os.path.dirname(p) == folder and rx.fullmatch(os.path.basename(p)):
            return True
    return False


def name_max(folder: str | os.PathLike[str]) -> int:
    """The longest file name (bytes) the file system of ``folder`` takes -- of its nearest
    existing folder when it does not exist yet (255 when it cannot say)."""
    f = Path(os.path.abspath(folder))
    f = next((p for p in (f, *f.parents) if p.is_dir()), f)
    try:
        return int(os.pathconf(f, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


_name_max = name_max


def _a(what: str) -> str:
    return f"{'an' if what[:1] in 'aeiou' else 'a'} {what}"


def check_outside_package(path: str | os.PathLike[str], label: str | None = None,
                          into_package: bool = False) -> None:
    """``DataError`` when ``path`` (a file or folder to write; real path) lies inside the installed
    fastdet package, unless ``into_package`` (the command's ``--into-package``)."""
    if into_package or not is_inside(path, PACKAGE_DIR):
        return
    name = os.fspath(path)
    raise DataError(f"{f'{label} {name}' if label else name}: is inside the installed fastdet package "
                    f"({PACKAGE_DIR}), whose files every later run uses; write elsewhere "
                    f"(`train {INTO_PACKAGE_FLAG}` replaces a bundled model on purpose)")


def check_output_folder(path: str | os.PathLike[str], label: str, into_package: bool = False) -> None:
    """A folder output (made if missing): not a file, writable or creatable, and outside the
    package (:func:`check_outside_package`). ``DataError`` otherwise."""
    out = Path(path)
    check_outside_package(out, label, into_package)
    if out.exists():
        if not out.is_dir():
            raise DataError(f"{label} {out}: exists and is not a folder")
        if not folder_writable(out):
            raise DataError(f"{label} {out}: folder is not writable")
        return
    parent = next((p for p in out.absolute().parents if p.exists()), None)
    if parent is None or not parent.is_dir() or not folder_writable(parent):
        raise DataError(f"{label} {out}: cannot create the folder ({parent} is not writable)")


def check_output(path: str | os.PathLike[str], what: str, label: str | None = None,
                 into_package: bool = False) -> None:
    """One output location (no comparison with other files): outside the package
    (:func:`check_outside_package`), its folder exists and is writable, and the name is not a
    folder. ``DataError`` otherwise."""
    name = os.fspath(path)
    shown = f"{label} {name}" if label else name
    if name != "" and not name.endswith(os.sep):
        check_outside_package(name, label, into_package)
    if name == "" or name.endswith(os.sep):
        raise DataError(f"{shown}: expected {_a(what)} file name")
    if os.path.isdir(name):
        raise DataError(f"{shown}: is a folder, expected {_a(what)} file name")
    if os.path.exists(name) and not os.path.isfile(name):
        # a device (/dev/null), a pipe, a socket: the finished output is renamed onto its
        # name, which would put a plain file in its place
        raise DataError(f"{shown}: is not a regular file (a device or a pipe); fastdet writes {_a(what)} "
                        f"file by renaming it into place: give a file name")
    if len(os.fsencode(os.path.basename(partial_name(name)))) > _name_max(os.path.dirname(os.path.abspath(name))):
        raise DataError(f"{shown}: the file name is too long (its temporary name would not fit the file system)")
    parent = os.path.dirname(os.path.abspath(name))
    if not os.path.isdir(parent):
        raise DataError(f"{shown}: output folder {parent} does not exist")
    if not folder_writable(parent):
        raise DataError(f"{shown}: output folder {parent} is not writable")


def check_paths(inputs: Iterable[Named], outputs: Iterable[tuple[str, str | os.PathLike[str] | None, str]],
                into_package: bool = False) -> None:
    """Check a command's files before any work (see the module docstring).

    inputs: ``(label, path)`` pairs, e.g. ``("--model", "m.npz")``; ``None`` paths and
        non-file sources are skipped, so are inputs that do not exist (their reader says so).
    outputs: ``(label, path, what)`` triples, e.g. ``("--boxes", "b.txt", "box")``;
        ``None`` paths are skipped.
    into_package: the outputs may lie inside the installed package (``--into-package``).
    """
    inputs = list(inputs)
    ins = [(label, os.fspath(p)) for label, p in inputs
           if p is not None and os.fspath(p) != "" and _is_file_input(os.fspath(p))
           and os.path.exists(os.fspath(p))]
    outs = [(label, os.fspath(p), what) for label, p, what in outputs if p is not None]
    for label, out, what in outs:
        check_output(out, what, label, into_package)
    for ilabel, p in inputs:
        if p is not None and _is_sequence(os.fspath(p)):
            for label, out, what in outs:
                if is_sequence_frame(out, os.fspath(p)):
                    raise DataError(f"{label} {out}: is a frame of the input image sequence {ilabel} {os.fspath(p)}; "
                                    f"give the {what} another name")
    for label, out, what in outs:
        for ilabel, inp in ins:
            if not os.path.isdir(inp) and _same(out, inp):
                raise DataError(f"{label} {out}: would overwrite the input {ilabel} {inp}; "
                                f"give the {what} another name")
    for i, (la, a, _) in enumerate(outs):
        for lb, b, _ in outs[i + 1:]:
            if _same(a, b):
                raise DataError(f"{la} {a} and {lb} {b} are one file: give each output its own name")


def is_inside(path: str | os.PathLike[str], folder: str | os.PathLike[str]) -> bool:
    """``path`` is ``folder`` or lies under it (real paths)."""
    p, f = os.path.realpath(path), os.path.realpath(folder)
    return p == f or p.startswith(f.rstrip(os.sep) + os.sep)

"""Docs that match the code: every ``fastdet`` command-line flag and every configuration field
the docs name exists.

Flags (:func:`flag_problems`, README.md and docs/cli.md): in a code span or a line of a code
block, ``fastdet SUB ...`` (also ``python -m fastdet SUB``, or a span that starts with a
command's name, as docs/cli.md's table does) names flags of ``SUB``: each must be one of its
options. A span of flags alone (```--no-refine```) must be an option of the command whose
section it is in (a ``## `video``` heading of docs/cli.md), or of some command outside such a
section. Spans and lines that run another program (``python -m tools...``, ``pytest``,
``dask``, ``pip``, ...) are not looked at.

Configuration fields (:func:`field_problems`, README.md and every docs/*.md):
``Name(field=...)`` and ``Name.field`` for each configuration class of :mod:`fastdet.config`
must name one of its fields (or, after a dot, an attribute of the class).

    python -m tools.check_docs          # one line per problem; exit 1 when there is one
"""
from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the files whose flags are checked
FLAG_DOCS = ("README.md", "docs/cli.md")
_FENCE = re.compile(r"^\s*```")
_SPAN = re.compile(r"`([^`\n]+(?:\n[^`\n]+)?)`")  # inline code, at most across one line break
_FLAG = re.compile(r"(?<![\w\-/.=])(--?[A-Za-z][\w-]*)")
_FASTDET = re.compile(r"(?:^|[\s(])(?:python3? -m )?fastdet (\S+)")
_SECTION = re.compile(r"^#+ .*?`([\w-]+)`")
#: a span or line that runs one of these is another program's command line
_OTHER = re.compile(r"^\s*(?:\$ )?(?:[A-Z_]+=\S+ )*(?:python3? (?!-m fastdet)|pytest|pip|dask|bash|git|ruff|mypy|"
                    r"ffmpeg|cd|ls|cp|mv|docker|\.ci/|\S+/)")
#: the options of ``fastdet`` before a command
TOP_LEVEL = ("-h", "--help", "--version")
#: shell text after which a command line's flags are no longer the command's
_END = re.compile(r"\s(?:\||&&|;|#|>|2>)\s?")


def command_flags() -> dict[str, set[str]]:
    """Every option string of each ``fastdet`` subcommand (``--help`` included)."""
    from fastdet.cli.main import build_parser

    parser = build_parser(None)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: {s for a in p._actions for s in a.option_strings} for name, p in sub.choices.items()}


def _pieces(text: str) -> Iterable[tuple[int, str, str | None]]:
    """``(line number, code text, section command)`` of each code span and code-block line of
    a markdown ``text``; the section command is the one a heading with a code name
    (``## `video```) opened, ``None`` outside such sections."""
    section: str | None = None
    fenced = python = False
    para: list[tuple[int, str]] = []
    held: tuple[int, str] | None = None  # a code-block line that ends in a backslash, continued

    def flush() -> Iterable[tuple[int, str, str | None]]:
        if not para:
            return
        block = "\n".join(line for _, line in para)
        for m in _SPAN.finditer(block):
            yield para[0][0] + block.count("\n", 0, m.start()), m.group(1).replace("\n", " "), section
        para.clear()

    for no, line in enumerate(text.splitlines(), 1):
        if _FENCE.match(line):
            yield from flush()
            fenced = not fenced
            python = fenced and line.strip()[3:].strip().lower() in ("python", "py", "pycon")
            continue
        if fenced:
            if python:  # Python code names no command-line flags
                continue
            if held is not None:
                no, line = held[0], held[1] + " " + line.strip()
            held = (no, line.rstrip()[:-1]) if line.rstrip().endswith("\\") else None
            if held is None:
                yield no, line, section
            continue
        if line.startswith("#"):
            yield from flush()
            m = _SECTION.match(line)
            section = m.group(1) if m else None
            continue
        if not line.strip():
            yield from flush()
            continue
        para.append((no, line))
    yield from flush()


def flag_problems(path: Path, flags: Mapping[str, set[str]]) -> list[str]:
    """One line per flag ``path`` names that its command does not have (module docstring)."""
    out = []
    every = set().union(*flags.values())
    text = path.read_text()
    name = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    for no, code, section in _pieces(text):
        code = code.strip()
        m = _FASTDET.search(code)
        first = code.split(" ", 1)[0]
        if m is not None and m.group(1).startswith("-"):  # the top level's own options
            command, rest = "", code[m.start(1):]
        elif m is not None and m.group(1).isupper():  # a placeholder (COMMAND): any command's
            command, rest = None, code[m.end():]
        elif m is not None:
            command, rest = m.group(1), code[m.end():]
        elif first in flags:
            command, rest = first, code[len(first):]
        elif _OTHER.match(code):
            continue
        else:
            command, rest = None, code
        if command == "":
            for flag in _FLAG.findall(rest):
                if flag not in TOP_LEVEL:
                    out.append(f"{name}:{no}: {flag} is not an option of `fastdet` itself")
            continue
        if command is not None and command not in flags:
            out.append(f"{name}:{no}: `fastdet {command}`: no such command")
            continue
        end = _END.search(rest)
        rest = rest[:end.start()] if end else rest
        for flag in _FLAG.findall(rest):
            if command is not None:
                ok, where = flag in flags[command], f"`fastdet {command}`"
            elif section in flags:
                ok, where = flag in flags[section], f"`fastdet {section}` (the section's command)"
            else:
                ok, where = flag in every, "any fastdet command"
            if not ok:
                out.append(f"{name}:{no}: {flag} is not an option of {where}")
    return out


def config_classes() -> dict[str, type]:
    """The configuration dataclasses of :mod:`fastdet.config`, by name."""
    import fastdet.config as cfg

    return {n: c for n in dir(cfg) if isinstance(c := getattr(cfg, n), type) and dataclasses.is_dataclass(c)}


def field_problems(path: Path, classes: Mapping[str, type]) -> list[str]:
    """One line per ``Name(field=...)`` or ``Name.field`` in ``path`` that ``Name`` (a class of
    ``classes``) does not have."""
    out = []
    text = path.read_text()
    name = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    names = "|".join(sorted(classes, key=len, reverse=True))
    for m in re.finditer(rf"(?<![\w.])({names})\(([^()]*)\)", text):
        fields = {f.name for f in dataclasses.fields(classes[m.group(1)])}
        for kw in re.findall(r"(?:^|[(,\s])(\w+)\s*=", m.group(2)):
            if kw not in fields:
                no = text.count("\n", 0, m.start()) + 1
                out.append(f"{name}:{no}: {m.group(1)} has no field {kw!r}")
    for m in re.finditer(rf"(?<![\w.])({names})\.(\w+)", text):
        cls, attr = classes[m.group(1)], m.group(2)
        if attr not in {f.name for f in dataclasses.fields(cls)} and not hasattr(cls, attr):
            no = text.count("\n", 0, m.start()) + 1
            out.append(f"{name}:{no}: {m.group(1)} has no field or attribute {attr!r}")
    return out


def problems(root: Path = ROOT) -> list[str]:
    """Every problem of the docs under ``root`` (module docstring)."""
    flags = command_flags()
    classes = config_classes()
    out = []
    for doc in FLAG_DOCS:
        out += flag_problems(root / doc, flags)
    for doc in [root / "README.md", *sorted((root / "docs").glob("*.md"))]:
        out += field_problems(doc, classes)
    return out


def main() -> int:
    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    found = problems()
    for line in found:
        print(line)
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())

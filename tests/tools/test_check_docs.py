"""tools/check_docs.py: the flags and configuration fields the docs name exist; a doc that
names a flag its command lacks, a command that does not exist or a field a config lacks is
found, line by line."""
from __future__ import annotations

import textwrap

from fastdet.config import NeighbourSplit, PipelineConfig
from tools.check_docs import field_problems, flag_problems, problems

FLAGS = {"video": {"-h", "--help", "-o", "--output", "--boxes", "--no-track"},
         "eval": {"-h", "--help", "--gt", "--all"}}


def _doc(tmp_path, text: str):
    p = tmp_path / "doc.md"
    p.write_text(textwrap.dedent(text))
    return p


def test_the_repository_s_docs_name_only_flags_and_fields_that_exist():
    assert problems() == []


def test_flags_are_checked_against_their_command_section_or_any_command(tmp_path):
    doc = _doc(tmp_path, """\
        Run `python -m fastdet video in.mp4 -o out.mp4 --boxes b.txt --gt x` and `fastdet eval --all`;
        `eval --gt G.txt --boxes B` as a table cell; `fastdet frobnicate --all`; `fastdet --help`, `fastdet --nope`.
        A flag alone: `--no-track`, `--gone`; another program's: `python -m tools.studies.x --gone`, `pytest --gone`.

        ```bash
        python -m fastdet eval --gt a.txt \\
            --gone 3 | grep --gone
        ```

        ```python
        from fastdet import video  # python -m fastdet video --gone (Python code: not looked at)
        ```

        ## `eval`

        Here `--boxes` is not eval's, `--all` is; `python -m fastdet video --boxes b.txt` is video's.
        """)
    got = flag_problems(doc, FLAGS)
    assert got == [
        f"{doc}:1: --gt is not an option of `fastdet video`",
        f"{doc}:2: --boxes is not an option of `fastdet eval`",
        f"{doc}:2: `fastdet frobnicate`: no such command",
        f"{doc}:2: --nope is not an option of `fastdet` itself",
        f"{doc}:3: --gone is not an option of any fastdet command",
        f"{doc}:6: --gone is not an option of `fastdet eval`",
        f"{doc}:16: --boxes is not an option of `fastdet eval` (the section's command)",
    ]


def test_config_fields_and_attributes_are_checked(tmp_path):
    doc = _doc(tmp_path, """\
        `PipelineConfig(split=NeighbourSplit(min_weight=0.2, min_aspect=2.0))`, `NeighbourSplit(bogus=1)`,
        `NeighbourSplit.min_weight`, `PipelineConfig.digest`, `PipelineConfig.nothing`.
        """)
    classes = {"PipelineConfig": PipelineConfig, "NeighbourSplit": NeighbourSplit}
    assert field_problems(doc, classes) == [f"{doc}:1: NeighbourSplit has no field 'bogus'",
                                            f"{doc}:2: PipelineConfig has no field or attribute 'nothing'"]

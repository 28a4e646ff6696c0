"""fastdet/batch/table.py: the combined box table of a batch, Parquet or CSV, against the boxes
files read line by line (x2 = left + width, y2 = top + height)."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from fastdet.batch.table import COLUMNS, table_format, write_table
from fastdet.errors import FastdetError

#: two boxes files: (frame, id, left, top, width, height, score)
FILES = {
    "road": ("1,3,10,20,30,40,0.75,-1,-1,-1\n1,-1,0.5,2,10.25,8,1.5,-1,-1,-1\n"
             "4,3,11,21,30,40,0.3333333432674408,-1,-1,-1\n"),
    "empty": "",
    "day2_oncoming": "2,7,100,50,64,24,2.125,-1,-1,-1\n",
}


def _files(tmp_path: Path) -> list[tuple[str, Path]]:
    out = []
    for name, text in FILES.items():
        p = tmp_path / f"{name}.boxes.txt"
        p.write_text(text)
        out.append((name, p))
    return out


def _expected() -> list[tuple]:
    rows = []
    for name, text in FILES.items():
        for line in text.splitlines():
            f, i, left, top, w, h, score = line.split(",")[:7]
            x1, y1 = float(left), float(top)
            rows.append((name, int(f), int(i), x1, y1, x1 + float(w), y1 + float(h), float(score)))
    return rows


def test_table_format_from_the_extension() -> None:
    assert table_format("a/b.parquet") == table_format("b.PQ") == "parquet"
    assert table_format("t.csv") == "csv"
    for bad in ("t.xlsx", "t", "t.csv.gz"):
        with pytest.raises(FastdetError, match=r"\.parquet or \.csv"):
            table_format(bad)


def test_csv_table_is_every_box_of_every_file_in_order(tmp_path: Path) -> None:
    out = tmp_path / "boxes.csv"
    assert write_table(out, _files(tmp_path)) == 4
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == COLUMNS
    got = [(r[0], int(r[1]), int(r[2]), *map(float, r[3:])) for r in rows[1:]]
    want = _expected()
    assert [g[:7] for g in got] == [w[:7] for w in want]
    # the score: the shortest text of the float32 it was
    assert [np.float32(g[7]) for g in got] == [np.float32(w[7]) for w in want]
    assert [r[7] for r in rows[1:]] == ["0.75", "1.5", "0.33333334", "2.125"]
    # coordinates as in the boxes files: whole numbers without ".0"
    assert rows[1][3:7] == ["10", "20", "40", "60"] and rows[2][3:7] == ["0.5", "2", "10.75", "10"]
    assert not list(tmp_path.glob(".*"))  # no temporary file left


def test_parquet_table_is_every_box_of_every_file_in_order(tmp_path: Path) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "boxes.parquet"
    assert write_table(out, _files(tmp_path)) == 4
    t = pq.read_table(out)
    assert tuple(t.column_names) == COLUMNS
    got = [tuple(r[c] for c in COLUMNS) for r in t.to_pylist()]
    want = _expected()
    assert [g[:7] for g in got] == [w[:7] for w in want]
    assert [g[7] for g in got] == [float(np.float32(w[7])) for w in want]


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_table_of_no_box_has_its_columns(tmp_path: Path, suffix: str) -> None:
    if suffix == ".parquet":
        pq = pytest.importorskip("pyarrow.parquet")
    (tmp_path / "e.txt").write_text("")
    out = tmp_path / f"boxes{suffix}"
    assert write_table(out, [("e", tmp_path / "e.txt")]) == 0
    if suffix == ".csv":
        assert out.read_text() == ",".join(COLUMNS) + "\n"
    else:
        t = pq.read_table(out)
        assert t.num_rows == 0 and tuple(t.column_names) == COLUMNS

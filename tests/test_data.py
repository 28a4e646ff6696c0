"""fastdet/data.py: where the shared data is: $FASTDET_DATA, else ../shared/data beside the
checkout, else beside or under the current folder."""
from __future__ import annotations

from pathlib import Path

from fastdet import data


def test_the_environment_variable_wins(tmp_path, monkeypatch):
    monkeypatch.setenv("FASTDET_DATA", str(tmp_path / "not-made-yet"))
    assert data.data_dir() == tmp_path / "not-made-yet"  # returned even if missing: callers say so


def test_the_first_folder_that_exists(tmp_path, monkeypatch):
    monkeypatch.delenv("FASTDET_DATA", raising=False)
    checkout = tmp_path / "checkout" / "shared" / "data"
    monkeypatch.setattr(data, "_CHECKOUT_DEFAULT", checkout)
    work = tmp_path / "a" / "b"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    assert data.data_dir() == checkout  # none exists: the checkout's, for the message
    (work / "shared" / "data").mkdir(parents=True)
    assert data.data_dir() == Path.cwd() / "shared" / "data"
    (tmp_path / "a" / "shared" / "data").mkdir(parents=True)
    assert data.data_dir() == Path.cwd().parent / "shared" / "data"  # beside before under
    checkout.mkdir(parents=True)
    assert data.data_dir() == checkout

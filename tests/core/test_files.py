"""Atomic writes: the old file survives a failed write and no temporary file is left behind."""

from __future__ import annotations

import os

import pytest

import satellite.files as files
from satellite.files import write_text_atomic


def test_write_replaces_the_file(tmp_path) -> None:  # type: ignore[no-untyped-def]
    p = tmp_path / "a.json"
    write_text_atomic(p, "one\n")
    write_text_atomic(p, "two\n")
    assert p.read_text(encoding="utf-8") == "two\n"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.json"]


def test_failed_rename_keeps_the_old_file(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    p = tmp_path / "a.json"
    p.write_text("old\n", encoding="utf-8")

    def boom(src: str, dst: str) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(files.os, "replace", boom)
    with pytest.raises(KeyboardInterrupt):
        write_text_atomic(p, "new\n")
    monkeypatch.setattr(files.os, "replace", os.replace)
    assert p.read_text(encoding="utf-8") == "old\n"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.json"]


def test_missing_directory_is_an_oserror(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(OSError):
        write_text_atomic(tmp_path / "no" / "a.json", "x")

"""Atomic writes: the old file survives a failed write and no temporary file is left behind."""

from __future__ import annotations

import os

import pytest

import isf_robot.support.files as files
from isf_robot.support.files import check_output_path, commit_partial, partial_path, write_text_atomic


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


def test_directory_and_device_targets_are_refused_before_writing(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.core import ConfigError

    with pytest.raises(ConfigError, match="is a directory"):
        write_text_atomic(tmp_path, "x")
    with pytest.raises(ConfigError, match="not a regular file"):
        check_output_path("/dev/null")
    assert list(tmp_path.iterdir()) == []


def test_partial_file_is_renamed_into_place_only_on_commit(tmp_path) -> None:  # type: ignore[no-untyped-def]
    target = tmp_path / "run.rrd"
    target.write_bytes(b"old")
    partial_path(target).write_bytes(b"new")
    assert target.read_bytes() == b"old" and partial_path(target).name == "run.rrd.partial"
    commit_partial(target)
    assert target.read_bytes() == b"new" and not partial_path(target).exists()


def test_written_files_get_ordinary_permissions(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.support.files import write_bytes_atomic

    old = os.umask(0o022)
    try:
        p = tmp_path / "a.png"
        write_bytes_atomic(p, b"\x89PNG")
        assert p.stat().st_mode & 0o777 == 0o644  # not the temporary file's owner-only 0o600
        os.chmod(p, 0o640)
        write_text_atomic(p, "again")
        assert p.stat().st_mode & 0o777 == 0o640 and p.read_bytes() == b"again"  # a replaced file keeps its mode
    finally:
        os.umask(old)

"""Files that appear complete under their name, or not at all (the one home of that rule).

Every file the project writes (JSON results, tau fits, gravity tables, recordings) is written
under a temporary name beside its target and renamed into place only when complete, so a bad
parameter, a crash or Ctrl-C leaves the previous file as it was:

* :func:`write_text_atomic` / :func:`write_bytes_atomic`: a whole text or byte string at once
  (temporary name hidden, removed on failure).
* :func:`partial_path` / :func:`check_output_path` / :func:`commit_partial`: for files written
  over a run (a recording): the run writes ``<name>.partial`` and renames it at the end; an
  interrupted run leaves ``<name>.partial`` (a name that says so) and the old ``<name>``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from isf_robot.core.exceptions import ConfigError

__all__ = ["write_text_atomic", "write_bytes_atomic", "partial_path", "check_output_path", "commit_partial",
           "PARTIAL_SUFFIX"]

PARTIAL_SUFFIX = ".partial"


def check_output_path(path: str | Path, what: str = "output file") -> Path:
    """Check that ``path`` can name an output file, before anything is written.

    Raises:
        ConfigError: ``path`` is a directory or a device/special file, or its folder is missing
            or not a folder (the message says which).

    """
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"{what} {str(p)!r} is a directory; give a file path")
    if p.exists() and not p.is_file():
        raise ConfigError(f"{what} {str(p)!r} exists and is not a regular file (a device or special file); "
                          "give a file path")
    parent = p.parent
    if parent.exists() and not parent.is_dir():
        raise ConfigError(f"{what} {str(p)!r}: {str(parent)!r} is not a directory")
    return p


def partial_path(path: str | Path) -> Path:
    """The name a file is written under until it is complete: ``<name>.partial`` beside it."""
    p = Path(path)
    return p.with_name(p.name + PARTIAL_SUFFIX)


def commit_partial(path: str | Path) -> Path:
    """Rename ``partial_path(path)`` to ``path`` (atomic on one file system); returns ``path``."""
    p = Path(path)
    os.replace(partial_path(p), p)
    return p


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to a temporary file next to ``path``, then rename it into place.

    An interrupted write leaves the previous file (or none) and no partial one under ``path``.

    Raises:
        ConfigError: ``path`` is a directory or special file.
        OSError: The directory is not writable or the disk is full (the temporary file is removed).

    """
    write_bytes_atomic(path, text.encode("utf-8"))


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to a temporary file next to ``path``, then rename it into place.

    The file gets the permissions any new file would (``0o666`` less the umask), or those of the
    file it replaces; not the owner-only ``0o600`` of the temporary file.

    Raises:
        ConfigError: ``path`` is a directory or special file.
        OSError: The directory is not writable or the disk is full (the temporary file is removed).

    """
    path = check_output_path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, _mode_for(path))
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _mode_for(path: Path) -> int:
    """Permission bits for a file written at ``path``: the existing file's, else ``0o666`` less the umask."""
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask

"""Atomic text writes: a file appears complete under its name, or not at all (STYLE.md, item 20)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["write_text_atomic"]


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to a temporary file next to ``path``, then rename it into place.

    An interrupted write leaves the previous file (or none) and no partial one under ``path``.

    Raises:
        OSError: The directory is not writable (the temporary file is removed).

    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise

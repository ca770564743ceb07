"""Helpers shared by the benchmark scripts (run them as ``python benchmarks/<name>.py``)."""

from __future__ import annotations

import platform
from collections.abc import Callable
from pathlib import Path

__all__ = ["cpu_model", "write_section"]


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (or what ``platform`` knows)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def write_section(path: Path, start: str, end: str, body: str,
                  write: Callable[[Path, str], None] | None = None) -> None:
    """Replace the text between the ``start`` and ``end`` markers of ``path`` with ``body``.

    The markers are kept; a file without them gets the section appended, a missing file is
    created with a ``# Benchmarks`` title. Other sections are left as they are. ``write(path,
    text)`` writes the file (e.g. an atomic writer; default ``Path.write_text``).
    """
    block = f"{start}\n{body}\n{end}"
    if path.exists():
        text = path.read_text(encoding="utf-8")
        if start in text and end in text:
            head, rest = text.split(start, 1)
            _, tail = rest.split(end, 1)
            text = head + block + tail
        else:
            text = text.rstrip("\n") + "\n\n" + block + "\n"
    else:
        text = "# Benchmarks\n\n" + block + "\n"
    if write is not None:
        write(path, text)
    else:
        path.write_text(text, encoding="utf-8")

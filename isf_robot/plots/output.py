"""matplotlib on demand (the optional ``plots`` extra) and figures written atomically and reproducibly."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from isf_robot.core import ConfigError
from isf_robot.support.extras import install_hint
from isf_robot.support.files import check_output_path, write_bytes_atomic

__all__ = ["PlotsUnavailableError", "require_matplotlib", "new_figure", "save_figure", "check_figure_path", "FORMATS"]

FORMATS = (".png", ".svg", ".pdf")
"""Figure file formats, picked by the output's suffix."""

_METADATA = {".png": {"Software": None}, ".svg": {"Date": None}, ".pdf": {"CreationDate": None}}
"""No date or version stamps, so the same data give the same file."""


class PlotsUnavailableError(ConfigError):
    """matplotlib is not installed."""


def require_matplotlib() -> Any:
    """Import and return :mod:`matplotlib`, or raise a one-line error naming the extra to install."""
    try:
        import matplotlib
    except ImportError:
        raise PlotsUnavailableError(
            f"plots need matplotlib, the 'plots' extra: {install_hint('plots')}") from None
    return matplotlib


def new_figure(width: float, height: float) -> Any:
    """A :class:`matplotlib.figure.Figure` (no pyplot: no global state, no GUI backend)."""
    require_matplotlib()
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), dpi=100, layout="constrained")


def check_figure_path(path: str | Path) -> Path:
    """The output path if its suffix names a format (:data:`FORMATS`) and it can be written."""
    p = check_output_path(path, "figure file")
    if p.suffix.lower() not in FORMATS:
        raise ConfigError(f"figure file {str(path)!r}: unknown format {p.suffix or '(none)'}; "
                          f"valid: {', '.join(FORMATS)}")
    return p


def save_figure(fig: Any, path: str | Path, dpi: float = 100.0) -> Path:
    """Render ``fig`` into memory, then write the file in one atomic step; returns the path."""
    p = check_figure_path(path)
    fmt = p.suffix.lower()
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt[1:], dpi=dpi, metadata=_METADATA[fmt])
    write_bytes_atomic(p, buf.getvalue())
    return p

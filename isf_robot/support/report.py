"""Output helpers shared by every command: JSON cleaning and plain-text tables.

One definition each, so that every JSON output and every table of the project follows the same
rules:

* :func:`to_jsonable`: numpy scalars and arrays become Python values, paths and unknown objects
  strings, objects with ``as_dict()`` their dict; **non-finite floats become ``null``** (JSON has
  no infinity or NaN; a reader sees "no value" rather than a string it must parse).
* :func:`format_table`: a header row, a rule and aligned columns (first column left-aligned,
  the others right-aligned); :func:`format_value` and :func:`mean_std_cell` format cells.
* :func:`with_schema`: every JSON document a command prints starts with
  ``"schema": "<name>/<version>"`` (:data:`SCHEMAS` holds the current version of each), so a
  reader can tell what it holds and whether its layout changed. A version is raised when a key
  is removed or changes meaning; new keys leave it as it is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import PurePath
from typing import Any

import numpy as np

__all__ = ["to_jsonable", "format_table", "format_value", "mean_std_cell", "with_schema", "schema_id", "SCHEMAS"]

SCHEMAS: dict[str, int] = {
    "isf-robot-run": 1,        # isf-robot run --json: one episode's metrics and parameters
    "isf-robot-compare": 1,    # isf-robot compare/demo --json: per strategy mean, std, episodes
    "isf-robot-compare-levels": 1,  # isf-robot compare --level velocity torque --json: a compare per level
    "isf-robot-compare-team": 1,  # isf-robot compare --json on several arms: per strategy/way, per-arm means
    "isf-robot-sweep": 1,      # isf-robot sweep --json/--output: per scene and point, summary + runs
    "isf-robot-replay": 1,     # isf-robot replay --json: {"recordings": [...]} for any number of inputs
    "isf-robot-core-demo": 1,  # isf-robot core-demo --json
    "isf-satellite-run": 1,    # isf-satellite run --json: one orbit run's summary
    "isf-satellite-study": 1,  # isf-satellite study: paired orbits, per-configuration summaries, CIs
}
"""Current version of each JSON document the commands print."""


def schema_id(name: str) -> str:
    """``"<name>/<version>"`` of a registered document kind (:data:`SCHEMAS`).

    Raises:
        KeyError: An unregistered name (a programming error: register it in :data:`SCHEMAS`).

    """
    return f"{name}/{SCHEMAS[name]}"


def with_schema(name: str, doc: Mapping[str, Any]) -> dict[str, Any]:
    """``doc`` as JSON-ready values with ``"schema": "<name>/<version>"`` as its first key."""
    out: dict[str, Any] = {"schema": schema_id(name)}
    out.update(to_jsonable({k: v for k, v in doc.items() if k != "schema"}))
    return out


def to_jsonable(obj: Any) -> Any:
    """Return ``obj`` as JSON-ready values (recursively); non-finite floats become ``None``."""
    if obj is None or isinstance(obj, (str, bool)):
        return obj
    if isinstance(obj, int):
        return obj
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return to_jsonable(obj.item())
    if isinstance(obj, PurePath):
        return str(obj)
    if hasattr(obj, "as_dict"):
        return to_jsonable(obj.as_dict())
    return str(obj)


def format_value(v: Any, fmt: str | None = None) -> str:
    """One table cell: ``-`` for ``None``; floats with ``fmt`` or about four significant digits."""
    if v is None:
        return "-"
    if isinstance(v, (bool, int, np.integer)) and not isinstance(v, float):
        return str(v)
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if not math.isfinite(f):
            return str(f)
        if fmt is not None:
            return format(f, fmt)
        return f"{f:.4g}" if abs(f) >= 1e-3 or f == 0 else f"{f:.3e}"
    return str(v)


def mean_std_cell(mean: float | None, std: float | None, fmt: str) -> str:
    """``mean ± std`` with ``fmt``; ``-`` when there is no mean."""
    if mean is None:
        return "-"
    return f"{mean:{fmt}} ± {(std or 0.0):{fmt}}"


def format_table(header: Sequence[str], rows: Sequence[Sequence[str]], *, title: str | None = None,
                 align_first_only: bool = False) -> str:
    """Plain-text table.

    Args:
        header: Column titles.
        rows: Cells (already formatted strings), one sequence per row.
        title: Optional line printed above the header.
        align_first_only: Left-align every column (for tables whose columns are labels);
            default: first column left, the others right-aligned.

    """
    cells = [list(header)] + [list(r) for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]

    def line(r: Sequence[str]) -> str:
        out = [r[0].ljust(widths[0])]
        for c, w in zip(r[1:], widths[1:]):
            out.append(c.ljust(w) if align_first_only else c.rjust(w))
        return "  ".join(out).rstrip()

    lines = [] if title is None else [title]
    lines.append(line(header))
    lines.append("  ".join("-" * w for w in widths))
    lines += [line(r) for r in rows]
    return "\n".join(lines)

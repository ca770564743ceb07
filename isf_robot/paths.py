"""Locating files shipped with the package (the MJCF ``models/`` folder)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["models_dir"]


def models_dir() -> Path:
    """Return the folder holding the MJCF models.

    In an installed wheel the repository's top-level ``models/`` folder is shipped as
    ``isf_robot/_models``; in a source checkout (editable install) it is ``<repo>/models``.
    """
    here = Path(__file__).resolve().parent
    for candidate in (here / "_models", here.parent / "models"):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(
        f"isf_robot models folder not found (looked in {here / '_models'} and {here.parent / 'models'})"
    )

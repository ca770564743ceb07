"""Locating files: the MJCF ``models/`` folder shipped with the package, and the shared data folder."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["models_dir", "shared_data_dir", "DATA_ENV"]

DATA_ENV = "ISF_ROBOT_DATA"
"""Environment variable naming the shared data folder (e.g. ``/work/shared/data``)."""


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


def shared_data_dir() -> Path:
    """Return the shared data folder (the Itokawa shape model and other inputs that are not committed).

    Looked for, in order: ``$ISF_ROBOT_DATA``; ``<checkout>/../shared/data`` beside a source checkout;
    ``../shared/data`` from the working directory (an installed package run from its checkout, as CI
    does). The first that exists wins; when none does, the checkout-relative path is returned so
    that errors name a path the user recognises.
    """
    env = os.environ.get(DATA_ENV)
    if env:
        return Path(env).expanduser()
    checkout = Path(__file__).resolve().parents[1].parent / "shared" / "data"
    for candidate in (checkout, Path.cwd().resolve().parent / "shared" / "data"):
        if candidate.is_dir():
            return candidate
    return checkout

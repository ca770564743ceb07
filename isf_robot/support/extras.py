"""How every message and document names an optional extra: one wording, from one place.

A wheel user installs the extra by the package's name, a checkout by its folder, so the hint
gives both: ``pip install 'isf-robot[plots]'`` (or ``pip install '.[plots]'`` from a checkout).
The extras are those of ``pyproject.toml``'s ``[project.optional-dependencies]``.
"""

from __future__ import annotations

__all__ = ["EXTRAS", "install_hint"]

EXTRAS = ("plots", "ray", "video", "test", "dev")
"""The optional extras of the ``isf-robot`` distribution."""


def install_hint(extra: str) -> str:
    """``pip install 'isf-robot[EXTRA]' (or pip install '.[EXTRA]' from a checkout)``.

    Raises:
        ValueError: ``extra`` is not one of :data:`EXTRAS`.

    """
    if extra not in EXTRAS:
        raise ValueError(f"unknown extra {extra!r}; valid: {', '.join(EXTRAS)}")
    return f"pip install 'isf-robot[{extra}]' (or pip install '.[{extra}]' from a checkout)"

"""The one export style of every package in this project.

Each package's ``__init__`` lists its public names in a table ``{name: submodule}`` and calls
:func:`lazy_exports`, which gives the package ``__all__``, a module ``__getattr__`` (PEP 562) that
imports the submodule on first use, and ``__dir__``. So ``from isf_robot.arm import Scene`` works
as usual, while ``import isf_robot.record`` (done by the CLI to register ``replay``) or
``import satellite`` imports neither rerun, mujoco nor scipy until a name is used, and the
public API of a package is readable in one table.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    package: str, exports: Mapping[str, str], namespace: dict[str, Any]
) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """Return ``(__all__, __getattr__, __dir__)`` for ``package``.

    Args:
        package: The package's ``__name__``.
        exports: Public name -> submodule (relative to ``package``) that defines it.
        namespace: The package's ``globals()`` (resolved names are cached there).

    """
    table = dict(exports)

    def __getattr__(name: str) -> Any:
        module = table.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(table))

    return sorted(table), __getattr__, __dir__

"""Exception hierarchy of isf_robot.

Every error the library raises on purpose derives from :class:`IsfError`. User errors
(bad shapes, NaN states, unknown names, invalid parameters) are :class:`ConfigError`,
which is also a :class:`ValueError`, so ``except ValueError`` keeps working for callers
who do not know this package.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

__all__ = [
    "IsfError",
    "ConfigError",
    "ShapeError",
    "NonFiniteError",
    "UnknownNameError",
    "InfeasibleFilterError",
    "SolverError",
    "PostJumpConditionError",
    "ZenoError",
    "IsfWarning",
]


class IsfError(Exception):
    """Root of every exception raised on purpose by isf_robot."""


class IsfWarning(UserWarning):
    """Warning category of isf_robot (filter relaxations, fallbacks, ...)."""


class ConfigError(IsfError, ValueError):
    """A parameter, configuration value or input is invalid."""


class ShapeError(ConfigError):
    """An array has the wrong shape."""


class NonFiniteError(ConfigError):
    """An array that must be finite holds NaN or infinity."""


class UnknownNameError(ConfigError, KeyError):
    """A name (scene, joint, geom, trigger, ...) is unknown; the message lists the valid ones.

    Args:
        kind: What kind of name it is, e.g. ``"scene"`` or ``"geom"``.
        name: The name that was asked for.
        valid: The names that exist.

    """

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.valid = tuple(sorted(str(v) for v in valid))
        shown = ", ".join(self.valid) if self.valid else "(none)"
        super().__init__(f"unknown {kind} {name!r}; valid {kind} names: {shown}")

    def __str__(self) -> str:  # KeyError would repr() the message otherwise
        return str(self.args[0])


class InfeasibleFilterError(IsfError):
    """The safety-filter QP has no solution satisfying every safety constraint.

    The evidence is attached so that the caller can inspect or log it.

    Attributes:
        qp: The :class:`~isf_robot.core.qp.FilterQP` that failed.
        state: The state at which it was built (or ``None`` when unknown).
        barrier_values: Barrier values ``h`` at that state, shape (k,).
        t: Time [s] of the failure, or ``None``.

    """

    def __init__(
        self,
        message: str,
        *,
        qp: Any = None,
        state: Any = None,
        barrier_values: Any = None,
        t: float | None = None,
    ) -> None:
        super().__init__(message)
        self.qp = qp
        self.state = state
        self.barrier_values = barrier_values
        self.t = t


class SolverError(IsfError):
    """The QP solver failed or returned a result that violates the constraints."""

    def __init__(self, message: str, *, qp: Any = None) -> None:
        super().__init__(message)
        self.qp = qp


class PostJumpConditionError(IsfError):
    """A safeguarding impulsive controller broke ``h(G(x,K(x))) >= 0`` or ``Xi(G(x,K(x))) >= c``.

    Attributes:
        t: Jump time [s].
        x_before: State before the jump.
        x_after: State after the jump.
        h_after: Barrier value after the jump.
        xi_after: Trigger value after the jump.
        c: The required margin.

    """

    def __init__(
        self,
        message: str,
        *,
        t: float,
        x_before: Any,
        x_after: Any,
        h_after: float,
        xi_after: float,
        c: float,
    ) -> None:
        super().__init__(message)
        self.t = t
        self.x_before = x_before
        self.x_after = x_after
        self.h_after = h_after
        self.xi_after = xi_after
        self.c = c


class ZenoError(IsfError):
    """Events accumulate (Zeno behaviour): the run is stopped.

    Attributes:
        t: Time [s] at which the guard fired.
        intervals: The most recent inter-event intervals [s].

    """

    def __init__(self, message: str, *, t: float, intervals: Any = None) -> None:
        super().__init__(message)
        self.t = t
        self.intervals = intervals

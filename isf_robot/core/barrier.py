"""Barrier functions ``h(x)``: safe set ``C = {x : h(x) >= 0}`` (paper, eq. safeset).

A concrete barrier gives :meth:`Barrier.value` and :meth:`Barrier.gradient` (and, for
time-varying barriers such as moving obstacles, :meth:`Barrier.time_derivative`); the base
class derives the rest once. Barriers are stateless.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .exceptions import ConfigError, ShapeError
from .validation import as_vector, check_finite_scalar, check_positive

__all__ = [
    "Barrier",
    "BarrierEval",
    "DiscObstacleBarrier",
    "HalfSpaceBarrier",
    "FunctionBarrier",
    "evaluate_barriers",
]


@dataclass(frozen=True)
class BarrierEval:
    """Values of k barriers at one state.

    Attributes:
        h: Barrier values, shape (k,).
        grad: Gradients ``dh/dx``, shape (k, n).
        dhdt: Explicit time derivatives ``dh/dt`` (0 for static barriers), shape (k,).
        names: One name per barrier.

    """

    h: np.ndarray
    grad: np.ndarray
    dhdt: np.ndarray
    names: tuple[str, ...]


class Barrier(ABC):
    """A continuously differentiable barrier ``h(x, t)``.

    Subclasses implement :meth:`value` and :meth:`gradient`; time-varying ones also
    :meth:`time_derivative`. ``name`` labels the barrier in results and logs.
    """

    name: str = "barrier"

    @abstractmethod
    def value(self, x: np.ndarray, t: float = 0.0) -> float:
        """Return ``h(x, t)``."""

    @abstractmethod
    def gradient(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Return ``dh/dx`` at ``(x, t)``, shape (n,)."""

    def time_derivative(self, x: np.ndarray, t: float = 0.0) -> float:
        """Return the explicit time derivative ``dh/dt`` (0 for a static barrier)."""
        return 0.0


class DiscObstacleBarrier(Barrier):
    """Keep a point out of a disc/ball: ``h(x) = |p - c(t)|^2 - r^2`` with ``p = x[dims]``.

    Args:
        center: Obstacle centre ``c``, shape (d,).
        radius: Obstacle radius ``r`` [m] (add any safety margin here), > 0.
        dims: Indices of the position inside the state, length d (default: the first d).
        velocity: Constant obstacle velocity [m/s], shape (d,), for a moving obstacle
            ``c(t) = center + velocity * t``.
        name: Label.

    """

    def __init__(
        self,
        center: Sequence[float] | np.ndarray,
        radius: float,
        dims: Sequence[int] | None = None,
        velocity: Sequence[float] | np.ndarray | None = None,
        name: str = "disc",
    ) -> None:
        self.center = as_vector(center, "center")
        d = self.center.shape[0]
        self.radius = check_positive(radius, "radius")
        self.dims = np.arange(d) if dims is None else np.asarray(dims, dtype=int)
        if self.dims.shape != (d,):
            raise ShapeError(f"dims must have {d} entries (one per centre coordinate), got {self.dims}")
        self.velocity = np.zeros(d) if velocity is None else as_vector(velocity, "velocity", d)
        self.name = name

    def _offset(self, x: np.ndarray, t: float) -> np.ndarray:
        return x[self.dims] - (self.center + self.velocity * t)

    def value(self, x: np.ndarray, t: float = 0.0) -> float:
        e = self._offset(x, t)
        return float(e @ e - self.radius**2)

    def gradient(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        g = np.zeros(x.shape[0])
        g[self.dims] = 2.0 * self._offset(x, t)
        return g

    def time_derivative(self, x: np.ndarray, t: float = 0.0) -> float:
        return float(-2.0 * self._offset(x, t) @ self.velocity)


class HalfSpaceBarrier(Barrier):
    """``h(x) = a^T x - b``: the half-space ``a^T x >= b``.

    Args:
        a: Normal, shape (n,), non-zero.
        b: Offset.
        name: Label.

    """

    def __init__(self, a: Sequence[float] | np.ndarray, b: float, name: str = "halfspace") -> None:
        self.a = as_vector(a, "a")
        if not np.any(self.a):
            raise ConfigError("half-space normal a must be non-zero")
        self.b = check_finite_scalar(b, "b")
        self.name = name

    def value(self, x: np.ndarray, t: float = 0.0) -> float:
        return float(self.a @ x - self.b)

    def gradient(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        return self.a.copy()


class FunctionBarrier(Barrier):
    """A barrier from user callables.

    Args:
        h: ``h(x, t) -> float``.
        grad: ``grad(x, t) -> (n,)``.
        dhdt: Optional ``dhdt(x, t) -> float``.
        name: Label.

    """

    def __init__(
        self,
        h: Callable[[np.ndarray, float], float],
        grad: Callable[[np.ndarray, float], np.ndarray],
        dhdt: Callable[[np.ndarray, float], float] | None = None,
        name: str = "function",
    ) -> None:
        if not callable(h) or not callable(grad) or (dhdt is not None and not callable(dhdt)):
            raise ConfigError("FunctionBarrier needs callables h(x, t), grad(x, t) and optional dhdt(x, t)")
        self._h, self._grad, self._dhdt = h, grad, dhdt
        self.name = name

    def value(self, x: np.ndarray, t: float = 0.0) -> float:
        return float(self._h(x, t))

    def gradient(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        return np.asarray(self._grad(x, t), dtype=float)

    def time_derivative(self, x: np.ndarray, t: float = 0.0) -> float:
        return 0.0 if self._dhdt is None else float(self._dhdt(x, t))


def evaluate_barriers(barriers: Sequence[Barrier], x: np.ndarray, t: float = 0.0) -> BarrierEval:
    """Evaluate several barriers at one state.

    Args:
        barriers: The barriers (at least one).
        x: State, shape (n,).
        t: Time [s].

    Returns:
        The stacked :class:`BarrierEval`.

    """
    if len(barriers) == 0:
        raise ConfigError("at least one barrier is needed")
    n = x.shape[0]
    k = len(barriers)
    h = np.empty(k)
    grad = np.empty((k, n))
    dhdt = np.empty(k)
    for i, b in enumerate(barriers):
        h[i] = b.value(x, t)
        gi = b.gradient(x, t)
        if gi.shape != (n,):
            raise ShapeError(f"barrier {b.name!r} returned a gradient of shape {gi.shape}, expected ({n},)")
        grad[i] = gi
        dhdt[i] = b.time_derivative(x, t)
    return BarrierEval(h=h, grad=grad, dhdt=dhdt, names=tuple(b.name for b in barriers))

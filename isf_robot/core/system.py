"""Control-affine systems ``x_dot = f0(x) + g(x) u + d`` with ``|d| <= d_bar`` (paper, eq. sys:nonlinear)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .barrier import BarrierEval
from .exceptions import ConfigError, ShapeError

__all__ = ["ControlAffineSystem", "SingleIntegrator", "FunctionSystem", "LieData", "lie_data"]

_new, _set = object.__new__, object.__setattr__  # (LieData._of: a frozen dataclass's __dict__ set whole)


class ControlAffineSystem(ABC):
    """``x_dot = f0(x, t) + g(x, t) u`` (the disturbance bound lives in the filter).

    Attributes:
        n: State dimension.
        m: Input dimension.

    """

    n: int
    m: int

    @abstractmethod
    def f0(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Drift, shape (n,)."""

    @abstractmethod
    def g(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Input matrix, shape (n, m)."""

    def dynamics(self, x: np.ndarray, u: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Return ``f0(x) + g(x) u``, shape (n,)."""
        return self.f0(x, t) + self.g(x, t) @ u


class SingleIntegrator(ControlAffineSystem):
    """``x_dot = u`` in ``dim`` dimensions (the arm's kinematic model, the demo's robot)."""

    def __init__(self, dim: int) -> None:
        if int(dim) != dim or dim < 1:
            raise ConfigError(f"dim must be a positive integer, got {dim!r}")
        self.n = self.m = int(dim)
        self._zero = np.zeros(self.n)
        self._eye = np.eye(self.n)

    def f0(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        return self._zero

    def g(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        return self._eye


class FunctionSystem(ControlAffineSystem):
    """A control-affine system from callables ``f0(x, t)`` and ``g(x, t)``.

    Args:
        n: State dimension.
        m: Input dimension.
        f0: Drift callable returning shape (n,).
        g: Input-matrix callable returning shape (n, m).

    """

    def __init__(
        self,
        n: int,
        m: int,
        f0: Callable[[np.ndarray, float], np.ndarray],
        g: Callable[[np.ndarray, float], np.ndarray],
    ) -> None:
        self.n, self.m = int(n), int(m)
        if self.n < 1 or self.m < 1:
            raise ConfigError(f"n and m must be >= 1, got n={n}, m={m}")
        self._f0, self._g = f0, g

    def f0(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        return np.asarray(self._f0(x, t), dtype=float)

    def g(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        return np.asarray(self._g(x, t), dtype=float)


@dataclass(frozen=True)
class LieData:
    """Per-barrier quantities at one state that the filters and triggers need.

    For barrier i: ``Lf h_i = dh_i/dx f0(x) + dh_i/dt`` (``lf``), ``Lg h_i = dh_i/dx g(x)``
    (``lg``), and ``|dh_i/dx|`` (``grad_norm``), so that ``Lf h_i(x, u) = lf_i + lg_i u``.

    Attributes:
        h: Barrier values, shape (k,).
        lf: Drift terms, shape (k,).
        lg: Input terms, shape (k, m).
        grad_norm: Gradient norms ``|dh/dx|``, shape (k,).
        names: One label per barrier.

    """

    h: np.ndarray
    lf: np.ndarray
    lg: np.ndarray
    grad_norm: np.ndarray
    names: tuple[str, ...] = ()

    @classmethod
    def _of(cls, h: np.ndarray, lf: np.ndarray, lg: np.ndarray, grad_norm: np.ndarray,
            names: tuple[str, ...] = ()) -> LieData:
        """The data with these fields, unchecked: the per-step producers' fast path.

        Same object as ``LieData(...)`` would build, without the frozen dataclass's
        field-by-field ``__init__``.
        """
        lie = _new(cls)
        _set(lie, "__dict__", {"h": h, "lf": lf, "lg": lg, "grad_norm": grad_norm, "names": names})
        return lie

    @property
    def k(self) -> int:
        """Number of barriers."""
        return int(self.h.shape[0])

    @property
    def m(self) -> int:
        """Input dimension."""
        return int(self.lg.shape[1])

    def select(self, rows: np.ndarray) -> LieData:
        """The barriers at ``rows`` (an index array), in that order."""
        names = self.names
        return LieData(self.h[rows], self.lf[rows], self.lg[rows], self.grad_norm[rows],
                       tuple(names[i] for i in rows.tolist()) if names else ())

    def validate(self) -> LieData:
        """Check shapes and finiteness; return self."""
        k = self.h.shape[0] if self.h.ndim == 1 else -1
        if k < 1 or self.lf.shape != (k,) or self.grad_norm.shape != (k,) or self.lg.ndim != 2 or self.lg.shape[0] != k:
            raise ShapeError(
                "LieData shapes must be h (k,), lf (k,), lg (k, m), grad_norm (k,); got "
                f"{self.h.shape}, {self.lf.shape}, {self.lg.shape}, {self.grad_norm.shape}"
            )
        for label, arr in (("h", self.h), ("lf", self.lf), ("lg", self.lg), ("grad_norm", self.grad_norm)):
            if not np.all(np.isfinite(arr)):
                from .exceptions import NonFiniteError

                raise NonFiniteError(f"barrier data {label} contains NaN or infinity: {arr}")
        return self


def lie_data(ev: BarrierEval, f0: np.ndarray, g: np.ndarray) -> LieData:
    """Combine barrier evaluations with the system's ``f0`` (n,) and ``g`` (n, m)."""
    if g.ndim != 2 or g.shape[0] != ev.grad.shape[1] or f0.shape != (ev.grad.shape[1],):
        raise ShapeError(f"f0 must be ({ev.grad.shape[1]},) and g ({ev.grad.shape[1]}, m); got {f0.shape}, {g.shape}")
    return LieData(
        h=ev.h,
        lf=ev.grad @ f0 + ev.dhdt,
        lg=ev.grad @ g,
        grad_norm=np.linalg.norm(ev.grad, axis=1),
        names=ev.names,
    )



"""Extended class-K functions ``alpha`` used in the barrier condition.

A function ``alpha: R -> R`` is (extended) class-K when ``alpha(0) = 0`` and it is strictly
increasing (paper, Notation). Every instance is validated at construction; a user callable
is checked on a sample grid, which cannot prove the property but catches the usual mistakes
(a constant offset, a decreasing function, a sign slip).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from .exceptions import ConfigError
from .validation import check_positive

__all__ = ["ClassK", "Linear", "Power", "CustomClassK", "as_class_k"]

_GRID = np.concatenate([-np.logspace(3, -6, 40), [0.0], np.logspace(-6, 3, 40)])


class ClassK(ABC):
    """Base class of extended class-K functions: ``alpha(0) = 0`` and strictly increasing."""

    @abstractmethod
    def __call__(self, h: float) -> float:
        """Return ``alpha(h)``."""

    def derivative(self, h: float) -> float:
        """Return ``d alpha / dh`` at ``h`` (central difference unless overridden)."""
        eps = 1e-6 * max(1.0, abs(h))
        return (self(h + eps) - self(h - eps)) / (2.0 * eps)

    def vector(self, h: np.ndarray) -> np.ndarray:
        """Apply ``alpha`` elementwise to an array of barrier values, shape (k,)."""
        return np.fromiter((self(float(v)) for v in h), dtype=float, count=len(h))

    def _validate(self) -> None:
        a0 = self(0.0)
        if not math.isfinite(a0) or abs(a0) > 1e-12:
            raise ConfigError(f"{self!r} is not class-K: alpha(0) = {a0}, must be 0")
        vals = np.array([self(float(v)) for v in _GRID])
        if not np.all(np.isfinite(vals)):
            raise ConfigError(f"{self!r} is not class-K: not finite on [-1e3, 1e3]")
        if not np.all(np.diff(vals) > 0.0):
            bad = int(np.argmin(np.diff(vals)))
            raise ConfigError(
                f"{self!r} is not class-K: not strictly increasing between h={_GRID[bad]:.3g} "
                f"and h={_GRID[bad + 1]:.3g} (alpha = {vals[bad]:.6g}, {vals[bad + 1]:.6g})"
            )


class Linear(ClassK):
    """``alpha(h) = gain * h``.

    Args:
        gain: Slope [1/s], > 0.

    """

    def __init__(self, gain: float) -> None:
        self.gain = check_positive(gain, "class-K gain")

    def __call__(self, h: float) -> float:
        return self.gain * h

    def derivative(self, h: float) -> float:
        return self.gain

    def vector(self, h: np.ndarray) -> np.ndarray:
        return self.gain * h

    def __repr__(self) -> str:
        return f"Linear(gain={self.gain:g})"


class Power(ClassK):
    """``alpha(h) = gain * sign(h) * |h|**exponent``.

    Args:
        gain: Scale, > 0.
        exponent: Power, > 0 (values below 1 make alpha steep near the boundary).

    """

    def __init__(self, gain: float, exponent: float) -> None:
        self.gain = check_positive(gain, "class-K gain")
        self.exponent = check_positive(exponent, "class-K exponent")

    def __call__(self, h: float) -> float:
        return math.copysign(self.gain * abs(h) ** self.exponent, h)

    def derivative(self, h: float) -> float:
        if h == 0.0 and self.exponent < 1.0:
            return math.inf
        return self.gain * self.exponent * abs(h) ** (self.exponent - 1.0)

    def vector(self, h: np.ndarray) -> np.ndarray:
        # (numpy's power loop may differ from the scalar libm pow in the last bit on some CPUs: the
        # vector and scalar forms agree to rounding, which is all the filters ask of them)
        h = np.asarray(h, dtype=float)
        return np.copysign(self.gain * np.abs(h) ** self.exponent, h)

    def __repr__(self) -> str:
        return f"Power(gain={self.gain:g}, exponent={self.exponent:g})"


class CustomClassK(ClassK):
    """A user callable, checked on a sample grid to be class-K.

    Args:
        fn: Function of one float returning a float.
        name: Label used in messages.

    """

    def __init__(self, fn: Callable[[float], float], name: str | None = None) -> None:
        if not callable(fn):
            raise ConfigError(f"class-K function must be callable, got {fn!r}")
        self.fn = fn
        self.name = name or getattr(fn, "__name__", "custom")
        self._validate()

    def __call__(self, h: float) -> float:
        return float(self.fn(h))

    def __repr__(self) -> str:
        return f"CustomClassK({self.name})"


def as_class_k(obj: ClassK | float | Callable[[float], float]) -> ClassK:
    """Turn a number (linear gain), a callable, or a :class:`ClassK` into a validated ClassK."""
    if isinstance(obj, ClassK):
        obj._validate()
        return obj
    if isinstance(obj, (int, float)) and not isinstance(obj, bool):
        return Linear(float(obj))
    if callable(obj):
        return CustomClassK(obj)
    raise ConfigError(f"alpha must be a ClassK, a positive number or a callable, got {obj!r}")

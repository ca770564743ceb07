"""Small input checks shared by the core (shapes, finiteness, positivity)."""

from __future__ import annotations

import math

import numpy as np

from .exceptions import ConfigError, NonFiniteError, ShapeError

__all__ = ["as_vector", "as_matrix", "check_positive", "check_nonnegative", "check_finite_scalar"]


def as_vector(value: object, name: str, size: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite float vector, raising a clear error otherwise.

    Args:
        value: Array-like.
        name: Name used in error messages.
        size: Required length, or ``None`` for any length.

    Returns:
        A 1-D float64 array (a view when possible).

    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name} must be a numeric vector, got {value!r}") from exc
    if arr.ndim == 0 and size == 1:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        want = size if size is not None else "n"
        raise ShapeError(f"{name} must be a vector of shape ({want},), got shape {arr.shape}")
    if size is not None and arr.shape[0] != size:
        raise ShapeError(f"{name} must have shape ({size},), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name} contains NaN or infinity: {arr}")
    return arr


def as_matrix(value: object, name: str, shape: tuple[int | None, int | None]) -> np.ndarray:
    """Return ``value`` as a finite float matrix of the given shape (``None`` = any)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name} must be a numeric matrix, got {value!r}") from exc
    want = tuple("*" if s is None else s for s in shape)
    if arr.ndim != 2 or any(s is not None and a != s for a, s in zip(arr.shape, shape)):
        raise ShapeError(f"{name} must have shape {want}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name} contains NaN or infinity")
    return arr


def check_finite_scalar(value: object, name: str) -> float:
    """Return ``value`` as a finite float (a number: not a bool or a string, which ``float`` would take)."""
    if isinstance(value, (bool, str, bytes)):
        raise ConfigError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(v):
        raise NonFiniteError(f"{name} must be finite, got {v}")
    return v


def check_positive(value: object, name: str) -> float:
    """Return ``value`` as a float, requiring ``value > 0``."""
    v = check_finite_scalar(value, name)
    if v <= 0.0:
        raise ConfigError(f"{name} must be > 0, got {v}")
    return v


def check_nonnegative(value: object, name: str) -> float:
    """Return ``value`` as a float, requiring ``value >= 0``."""
    v = check_finite_scalar(value, name)
    if v < 0.0:
        raise ConfigError(f"{name} must be >= 0, got {v}")
    return v

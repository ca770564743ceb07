"""Uniform cubic B-splines on the gravity grids: the weights, the prefilter through node values, ghost nodes.

The shell table (:mod:`satellite.gravity.table`), its near-surface tiles (:mod:`satellite.gravity.near`) and the
fine boxes (:mod:`satellite.gravity.fine`) all interpolate with these.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from satellite.compiled import inlined

__all__ = ["RG", "bspline3", "dbspline3", "prefilter", "pad_nodes"]

_GHOSTS = 6
"""Radial ghost nodes (cubic extrapolation) on each side for the prefilter: edge effects ~0.27^6."""

RG = 3
"""Radial ghost coefficient layers a table keeps on each side (its spline reaches two cells below ``r_lo``)."""


@inlined
def bspline3(t: Any) -> tuple[Any, Any, Any, Any]:
    """Uniform cubic B-spline weights of the coefficients ``i-1 .. i+2`` at fraction ``t`` of cell ``[i, i+1]``."""
    t2, t3 = t * t, t * t * t
    u = 1.0 - t
    return (u * u * u / 6.0, (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0, (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
            t3 / 6.0)


@inlined
def dbspline3(t: Any) -> tuple[Any, Any, Any, Any]:
    """Derivatives with respect to ``t`` of :func:`bspline3`'s weights (they sum to 0)."""
    t2 = t * t
    u = 1.0 - t
    return -0.5 * u * u, 1.5 * t2 - 2.0 * t, -1.5 * t2 + t + 0.5, 0.5 * t2


def prefilter(values: NDArray[np.float64], ghosts: int = 0) -> NDArray[np.float64]:
    """B-spline coefficients whose spline passes through ``values`` (shape (n_r, n_lat, n_lon, 3)).

    Latitude: each pair of meridians half a turn apart forms one periodic great circle (up one,
    over the pole, down the other). Longitude: periodic. Radius: ``_GHOSTS`` nodes of cubic
    extrapolation on each side, mirror beyond them; ``ghosts`` (<= ``_GHOSTS``) of their
    coefficient layers are kept on each side (shape (n_r + 2 ghosts, ...)).
    """
    from scipy.ndimage import spline_filter1d  # (deferred: scipy.ndimage loads when a table is first read or built)

    n_r, n_lat, n_lon, _ = values.shape
    half = n_lon // 2
    circle = np.concatenate([values[:, :, :half], values[:, ::-1, half:]], axis=1)
    circle = spline_filter1d(circle, 3, axis=1, mode="grid-wrap")
    c = np.concatenate([circle[:, :n_lat], circle[:, n_lat:][:, ::-1]], axis=2)
    c = spline_filter1d(c, 3, axis=2, mode="grid-wrap")
    m = np.arange(1, _GHOSTS + 1, dtype=np.float64)
    lag = np.stack([(-m - 1) * (-m - 2) * (-m - 3) / -6.0, -m * (-m - 2) * (-m - 3) / 2.0,
                    -m * (-m - 1) * (-m - 3) / -2.0, -m * (-m - 1) * (-m - 2) / 6.0], axis=1)  # at -m from 0..3
    lo = np.einsum("gn,n...->g...", lag, c[:4])[::-1]
    hi = np.einsum("gn,n...->g...", lag, c[-1:-5:-1])
    ext = np.concatenate([lo, c, hi], axis=0)
    ext = spline_filter1d(ext, 3, axis=0, mode="mirror")
    return np.ascontiguousarray(ext[_GHOSTS - ghosts: _GHOSTS + n_r + ghosts])


def pad_nodes(values: NDArray[np.float64], n_lat: int) -> NDArray[np.float64]:
    """Ghost nodes: two latitude rows past each pole (half a turn away), two longitudes wrapped on each side."""
    half = values.shape[2] // 2
    flip = np.roll(values, half, axis=2)
    lat = np.concatenate([flip[:, 1::-1], values, flip[:, : n_lat - 3: -1]], axis=1)
    return np.concatenate([lat[:, :, -2:], lat, lat[:, :, :2]], axis=2)



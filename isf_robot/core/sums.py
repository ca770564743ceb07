"""Small sums of products in one written order (elementwise numpy, no BLAS): the same numbers on every machine.

numpy's BLAS products (``@``, ``dot``) and ``einsum`` add their terms in an order that depends on the
CPU (OpenBLAS picks its kernels at run time; einsum's SIMD loop keeps as many partial sums as the
vector width). These functions make each product and each sum one correctly rounded IEEE operation
in a written order instead. Users: the arm's barrier rows, reaching controller and tracking error,
whose compiled kernels (:mod:`isf_robot.arm.kernels`) make the same operations in the same order;
the metrics' and MIET samples' norms; the satellite's plane basis and total ``|dv|``, where the
orbit amplifies a last-bit difference over thousands of hours. The filter step itself does not use
them (:mod:`isf_robot.core.robust`: its compiled and plain passes agree to a tolerance).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["combine3", "dot", "dots3", "gram", "norm", "row_norms", "row_sq_sums", "sq_sum"]


def sq_sum(e: np.ndarray) -> float:
    """``e . e`` of a vector: ``((0 + e_0^2) + e_1^2) + ...``, in index order."""
    s = 0.0
    for x in e.tolist():
        s += x * x
    return s


def norm(e: np.ndarray) -> float:
    """``|e|`` of a vector: ``sqrt(sq_sum(e))`` (``np.linalg.norm`` of a vector is BLAS's dot, CPU-dependent)."""
    return math.sqrt(sq_sum(e))


def row_sq_sums(g: np.ndarray) -> np.ndarray:
    """``g_i . g_i`` of the rows of a (k, n) array: the squares added in column order (``sq_sum`` of each row)."""
    if g.shape[1] == 0:
        return np.zeros(g.shape[0])
    return np.add.accumulate(g * g, axis=1)[:, -1].copy()  # (accumulate: strictly in order)


def row_norms(g: np.ndarray) -> np.ndarray:
    """``|g_i|`` of the rows of a (k, n) array: :func:`row_sq_sums`, then the square root."""
    return np.sqrt(row_sq_sums(g))


def dots3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a_i . b_i`` of the rows of two (k, 3) arrays: ``((0 + a_0 b_0) + a_1 b_1) + a_2 b_2``."""
    return ((0.0 + a[:, 0] * b[:, 0]) + a[:, 1] * b[:, 1]) + a[:, 2] * b[:, 2]


def combine3(w: np.ndarray, jac: np.ndarray) -> np.ndarray:
    """``w^T J``: ``((0 + w_0 J_0) + w_1 J_1) + w_2 J_2`` of the rows ``J_r`` of ``jac``.

    ``w`` of shape (..., 3) and ``jac`` of shape (..., 3, m) (a batch: one ``w`` per block), or
    ``w`` (3,) and ``jac`` (3, m); the result has shape (..., m).
    """
    w0, w1, w2 = w[..., 0, None], w[..., 1, None], w[..., 2, None]
    return ((0.0 + w0 * jac[..., 0, :]) + w1 * jac[..., 1, :]) + w2 * jac[..., 2, :]


def gram(jac: np.ndarray) -> np.ndarray:
    """``J J^T`` of a (r, n) array: entry (a, b) is ``J_a0 J_b0 + J_a1 J_b1 + ...`` added in order, from the first.

    C-contiguous, shape (r, r) (zeros for n = 0).
    """
    if jac.shape[1] == 0:
        return np.zeros((jac.shape[0], jac.shape[0]))
    return np.add.accumulate(jac[:, None, :] * jac[None, :, :], axis=2)[:, :, -1].copy()


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """``a . b`` of two vectors: the products added in index order, from the first (``matvec``'s order; 0 if empty)."""
    al, bl = a.tolist(), b.tolist()
    if not al:
        return 0.0
    s = al[0] * bl[0]
    for i in range(1, len(al)):
        s += al[i] * bl[i]
    return s

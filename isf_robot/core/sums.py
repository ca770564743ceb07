"""Small sums of products in one written order (elementwise numpy, no BLAS): the same numbers on every machine.

numpy's BLAS products (``@``, ``dot``) and ``einsum`` add their terms in an order that depends on the
CPU (OpenBLAS picks its kernels at run time; einsum's SIMD loop keeps as many partial sums as the
vector width). These functions make each product and each sum one correctly rounded IEEE operation
in a written order instead. Users: the metrics' and MIET samples' norms and the arm recorder's; the
satellite's plane basis and total ``|dv|``, where the orbit amplifies a last-bit difference over
thousands of hours. The filter step and the arm's rows and controllers do not use them (their
compiled and plain paths agree to a tolerance).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["dot", "norm", "row_sq_sums", "sq_sum"]


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


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """``a . b`` of two vectors: the products added in index order, from the first (``matvec``'s order; 0 if empty)."""
    al, bl = a.tolist(), b.tolist()
    if not al:
        return 0.0
    s = al[0] * bl[0]
    for i in range(1, len(al)):
        s += al[i] * bl[i]
    return s

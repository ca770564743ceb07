"""The rows the collision barriers give a filter at one state: NearPairs, FilterRows, TickRows.

Made by :class:`~isf_robot.arm.narrow.NarrowPhase` (:meth:`CollisionBarriers.near`, ``rows``,
``lie_rows``); kept apart from it as the types its callers read.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from isf_robot.core import LieData

__all__ = ["FilterRows", "NearPairs", "TickRows"]


class NearPairs(NamedTuple):
    """The collision pairs within the cut-off at one state (:meth:`CollisionBarriers.near`).

    Attributes:
        rows: Their pair indices, ascending, shape (j,) int64.
        row_list: The same as a list.
        h: ``dist - margin``, shape (j,).
        grad: ``dh/dq``, shape (j, n).
        dhdt: ``dh/dt``, shape (j,).
        witness: Witness points (on geom 1, on geom 2) [m], shape (j, 2, 3), when asked for.
        h_min: Smallest ``h`` (``inf`` when no pair is near).
        dist_min: Smallest distance [m] (``inf`` when no pair is near).

    """

    rows: np.ndarray
    row_list: list[int]
    h: np.ndarray
    grad: np.ndarray
    dhdt: np.ndarray
    witness: np.ndarray | None
    h_min: float
    dist_min: float


class FilterRows(NamedTuple):
    """The rows of a filter at one state (:meth:`CollisionBarriers.rows`).

    Attributes:
        near: The collision pairs within the cut-off.
        h: Their ``h``, then the joint-limit values, shape (j + l,).
        grad: Their ``dh/dq``, then the joint-limit rows (``+-e_i``), shape (j + l, n).
        joint_min: The smallest joint-limit value (``inf`` without joint rows).
        grad_norm: ``|dh/dq|`` of every row,
            shape (j + l,), or ``None``
            (not computed: the caller computes it).
        lf: ``dh/dt`` of every row (the pairs', then zeros for the joint rows), shape (j + l,).

    """

    near: NearPairs
    h: np.ndarray
    grad: np.ndarray
    joint_min: float
    grad_norm: np.ndarray | None = None
    lf: np.ndarray | None = None


class TickRows(NamedTuple):
    """The filter's rows at one state and what the tick's accounting needs (:meth:`CollisionBarriers.lie_rows`).

    Attributes:
        lie: ``lie(rows(...))``: the Lie data of the near pairs, then the joint limits.
        rows: The near pairs' indices, ascending, shape (j,) int64 (``near.rows``).
        row_list: The same as a tuple (``near.row_list``'s items; one object per set of near pairs, shared).
        h_min: Smallest ``h`` of the near pairs (``inf`` when none is near).
        dist_min: Their smallest distance [m] (``inf`` when none is near).
        joint_min: The smallest joint-limit value.
        witness: The near pairs' witness points when asked for (``lie_rows(..., witness=True)``), else
            ``None``: ``witness[:, 0]`` on geom 1, ``witness[:, 1]`` on geom 2 [m]; shape (j, 3, 3) from
            the compiled kernel (its third row the unit normal), (j, 2, 3) otherwise.

    """

    lie: LieData
    rows: np.ndarray
    row_list: tuple[int, ...]
    h_min: float
    dist_min: float
    joint_min: float
    witness: np.ndarray | None

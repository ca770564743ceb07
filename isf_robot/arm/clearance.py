"""True minimum signed distance over a set of geom pairs (no cut-off, no margin, no Jacobians)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from .pairs import CollisionPairs

__all__ = ["Clearance", "min_distance"]


@dataclass(frozen=True)
class Clearance:
    """Smallest signed distance over a set of pairs.

    Attributes:
        distance: Signed distance [m] (negative: penetration depth).
        index: Index of the closest pair.
        name: Its name.

    """

    distance: float
    index: int
    name: str


class _ClearanceSearch:
    """Precomputed index arrays for :func:`min_distance` over a fixed set of pairs."""

    def __init__(self, model: mujoco.MjModel, pairs: CollisionPairs) -> None:
        k = pairs.k
        self.model = model
        self.names = pairs.names
        self.g1, self.g2 = pairs.geom1.tolist(), pairs.geom2.tolist()
        self.dmat = np.zeros((k, model.ngeom))
        self.dmat[np.arange(k), pairs.geom1] += 1.0
        self.dmat[np.arange(k), pairs.geom2] -= 1.0
        rb1, rb2 = model.geom_rbound[pairs.geom1], model.geom_rbound[pairs.geom2]
        # Unbounded geoms (planes, rbound 0) get an infinite allowance: always searched first.
        self.rbsum = np.where((rb1 == 0) | (rb2 == 0), np.inf, rb1 + rb2)

    def __call__(self, data: mujoco.MjData) -> Clearance:
        diff = self.dmat @ data.geom_xpos
        bound = np.sqrt(np.einsum("ij,ij->i", diff, diff)) - self.rbsum
        order = np.argsort(bound).tolist()
        bounds = bound.tolist()
        m, g1, g2 = self.model, self.g1, self.g2
        geom_distance = mujoco.mj_geomDistance
        best, best_i = math.inf, order[0]
        for i in order:
            if bounds[i] >= best:
                break
            d = geom_distance(m, data, g1[i], g2[i], best if best < math.inf else 1e6, None)
            if d < best:
                best, best_i = d, i
        return Clearance(distance=float(best), index=int(best_i), name=self.names[best_i])


def min_distance(model: mujoco.MjModel, data: mujoco.MjData, pairs: CollisionPairs) -> Clearance:
    """True minimum signed distance over all pairs: no cut-off, no margin, no Jacobians.

    Pairs are visited in order of their bounding-sphere distance (a lower bound on the true
    distance) and the search stops once that bound exceeds the best distance found.
    Needs the kinematics of the current state (``mj_kinematics`` or ``mj_forward``).
    :meth:`CollisionBarriers.min_distance` does the same with its index arrays precomputed.
    """
    return _ClearanceSearch(model, pairs)(data)

"""Barriers of the arm from MuJoCo geometry: collision pairs and joint limits.

This module is the public face of smaller ones, and every name stays importable from here:

* :mod:`.batch`: :class:`BarrierBatch` (values, ``dh/dq``, ``dh/dt`` of k barriers) and
  :func:`stack_batches`;
* :mod:`.pairs`: which geom pairs get a barrier (:func:`collision_pairs`);
* :mod:`.broadphase`: which pairs are near enough to need ``mj_geomDistance``;
* :mod:`.collision`: :class:`CollisionBarriers`, ``h = min(dist, cutoff) - margin`` (the
  formulas and their accuracy are in that module's docstring);
* :mod:`.joint_limits`: :class:`JointLimitBarriers`;
* :mod:`.clearance`: the true minimum distance (:func:`min_distance`, :class:`Clearance`).
"""

from __future__ import annotations

from .batch import BarrierBatch, stack_batches
from .clearance import Clearance, min_distance
from .collision import CollisionBarriers
from .joint_limits import JointLimitBarriers
from .pairs import CollisionPairs, collision_pairs

__all__ = [
    "BarrierBatch",
    "stack_batches",
    "CollisionPairs",
    "collision_pairs",
    "CollisionBarriers",
    "JointLimitBarriers",
    "Clearance",
    "min_distance",
]

"""Barrier rows of the arm at one state: values, gradients, time derivatives.

The filter acts on the kinematic model ``q_dot = u + d`` of the n arm joints, so for every
barrier it needs ``h``, ``dh/dq`` (= ``Lg h``, shape (n,)) and the explicit time derivative
``dh/dt`` (= ``Lf h``: moving obstacles). :class:`BarrierBatch` carries them for k barriers;
:class:`~isf_robot.arm.collision.CollisionBarriers` and
:class:`~isf_robot.arm.joint_limits.JointLimitBarriers` produce them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from isf_robot.core.exceptions import ConfigError, ShapeError
from isf_robot.core.system import LieData

__all__ = ["BarrierBatch", "stack_batches"]


@dataclass(frozen=True, eq=False)
class BarrierBatch:
    """Values and derivatives of k barriers at one state.

    Attributes:
        h: Barrier values, shape (k,) ([m] for collisions, [rad] for joint limits).
        grad: ``dh/dq`` w.r.t. the arm joints, shape (k, n).
        dhdt: Explicit time derivative ``dh/dt`` (moving obstacles), shape (k,).
        names: One label per barrier, e.g. ``"link2_geom|pole_a"`` or ``"j1:min"``.
        active: False where the pair was skipped by the cut-off (``h`` saturated, zero
            gradient), shape (k,).
        witness: Witness points (on geom 1, on geom 2) [m], shape (k, 2, 3); NaN for rows
            without geometry (joint limits) and for inactive pairs.
        pair_geoms: Geom ids of each pair, shape (k, 2); -1 for joint-limit rows.

    Arrays that do not change between calls (``pair_geoms``; the constant parts of
    joint-limit batches) are shared and read-only: copy them before modifying.

    """

    h: np.ndarray
    grad: np.ndarray
    dhdt: np.ndarray
    names: tuple[str, ...]
    active: np.ndarray
    witness: np.ndarray
    pair_geoms: np.ndarray

    @classmethod
    def _of(cls, h: np.ndarray, grad: np.ndarray, dhdt: np.ndarray, names: tuple[str, ...],
            active: np.ndarray, witness: np.ndarray, pair_geoms: np.ndarray) -> BarrierBatch:
        """The batch with these fields, unchecked (the per-step producers' fast path).

        Same object as ``BarrierBatch(...)`` would build, without the frozen dataclass's
        field-by-field ``__init__`` (about 1 us per call).
        """
        batch = object.__new__(cls)
        batch.__dict__.update(h=h, grad=grad, dhdt=dhdt, names=names, active=active,
                              witness=witness, pair_geoms=pair_geoms)
        return batch

    @property
    def k(self) -> int:
        """Number of barriers."""
        return int(self.h.shape[0])

    def to_lie_data(self) -> LieData:
        """The core's :class:`~isf_robot.core.system.LieData` for ``q_dot = u + d``.

        With f0 = 0 and g = I: ``Lf h = dh/dt``, ``Lg h = dh/dq``, ``|dh/dx| = |dh/dq|``.
        """
        return LieData(h=self.h, lf=self.dhdt, lg=self.grad,
                       grad_norm=np.linalg.norm(self.grad, axis=1), names=self.names)


def stack_batches(*batches: BarrierBatch) -> BarrierBatch:
    """Concatenate batches row-wise (all must have the same number of joints n)."""
    if not batches:
        raise ConfigError("stack_batches needs at least one batch")
    n = {b.grad.shape[1] for b in batches}
    if len(n) != 1:
        raise ShapeError(f"batches have different joint counts {sorted(n)}")
    return BarrierBatch(
        h=np.concatenate([b.h for b in batches]),
        grad=np.concatenate([b.grad for b in batches]),
        dhdt=np.concatenate([b.dhdt for b in batches]),
        names=tuple(x for b in batches for x in b.names),
        active=np.concatenate([b.active for b in batches]),
        witness=np.concatenate([b.witness for b in batches]),
        pair_geoms=np.concatenate([b.pair_geoms for b in batches]),
    )

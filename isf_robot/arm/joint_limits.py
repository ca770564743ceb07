"""Joint-limit barriers of the arm: two rows per limited joint, constant gradients."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from isf_robot.core.exceptions import ConfigError, ShapeError
from isf_robot.core.jit import formula

from .batch import BarrierBatch

if TYPE_CHECKING:
    from .scene import Scene

__all__ = ["JointLimitBarriers", "joint_value"]


@formula
def joint_value(sign, q, offset):  # type: ignore[no-untyped-def]
    """A joint-limit row's value ``h = sign q + offset`` (floats or arrays; see :attr:`JointLimitBarriers.tables`)."""
    return sign * q + offset


class JointLimitBarriers:
    """Joint-limit barriers ``h = q - q_min - margin`` and ``h = q_max - margin - q``.

    Rows are ordered ``[j1:min, j1:max, j2:min, ...]`` over the limited joints;
    ``dh/dq`` is ``+e_i`` / ``-e_i``, ``dh/dt = 0``.

    Args:
        qpos_adr: qpos addresses of the arm joints, shape (n,).
        joint_range: Limits [rad or m], shape (n, 2); unlimited joints (inf) get no rows.
        margin: Margin [rad or m], >= 0.
        joint_names: One name per joint.

    """

    def __init__(self, qpos_adr: Sequence[int] | np.ndarray, joint_range: np.ndarray, margin: float,
                 joint_names: Sequence[str]) -> None:
        rng = np.asarray(joint_range, dtype=float)
        n = len(qpos_adr)
        if rng.shape != (n, 2) or len(joint_names) != n:
            raise ShapeError(f"joint_range must have shape ({n}, 2) and {n} names; got "
                             f"{rng.shape} and {len(joint_names)} names")
        if margin < 0:
            raise ConfigError(f"joint-limit margin must be >= 0 [rad], got {margin}")
        limited = np.nonzero(np.isfinite(rng).all(axis=1))[0]
        width = rng[limited, 1] - rng[limited, 0]
        if np.any(width <= 2 * margin):
            raise ConfigError(f"joint-limit margin {margin} leaves no room in some joint range")
        self._qadr = np.repeat(np.asarray(qpos_adr, dtype=np.int64)[limited], 2)
        self._sign = np.tile([1.0, -1.0], limited.size)
        self._offset = np.empty(2 * limited.size)
        self._offset[0::2] = -(rng[limited, 0] + margin)
        self._offset[1::2] = rng[limited, 1] - margin
        self._grad = np.zeros((2 * limited.size, n))
        self._grad[np.arange(2 * limited.size), np.repeat(limited, 2)] = self._sign
        self.names = tuple(f"{joint_names[int(i)]}:{s}" for i in limited for s in ("min", "max"))
        # Constant parts of every result, shared between calls and therefore read-only.
        k = self._sign.size
        self._const = {
            "grad": self._grad, "dhdt": np.zeros(k), "active": np.ones(k, dtype=bool),
            "witness": np.full((k, 2, 3), np.nan), "pair_geoms": np.full((k, 2), -1, dtype=np.int64),
        }
        for arr in self._const.values():
            arr.flags.writeable = False
        self._tables = (np.ascontiguousarray(self._qadr), np.ascontiguousarray(self._sign),
                        np.ascontiguousarray(self._offset), self._grad)

    @classmethod
    def from_scene(cls, scene: Scene) -> JointLimitBarriers:
        """Limits of a scene's arm joints with its config's joint margin."""
        return cls(scene.qpos_adr, scene.joint_range, scene.config.barrier.joint_margin,
                   scene.joint_names)

    def evaluate(self, data: mujoco.MjData) -> BarrierBatch:
        """Barrier rows at ``data.qpos`` (no kinematics needed).

        Only ``h`` is computed; ``grad``, ``dhdt``, ``active``, ``witness`` and ``pair_geoms``
        are constant, shared, read-only arrays.
        """
        return self.batch(self.values(data))

    @property
    def grad(self) -> np.ndarray:
        """``dh/dq`` of every row, shape (k, n): constant, shared, read-only."""
        return self._grad

    @property
    def tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(qpos address, sign, offset, grad)`` per row: ``h = sign q[adr] + offset`` (read-only)."""
        return self._tables

    def values(self, data: mujoco.MjData) -> np.ndarray:
        """The barrier values ``h`` at ``data.qpos``, shape (k,) (the rest of a batch is constant)."""
        return joint_value(self._sign, data.qpos[self._qadr], self._offset)

    def batch(self, h: np.ndarray) -> BarrierBatch:
        """The batch of the values ``h`` (from :meth:`values`)."""
        c = self._const
        return BarrierBatch._of(h, c["grad"], c["dhdt"], self.names, c["active"], c["witness"],
                                c["pair_geoms"])

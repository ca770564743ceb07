"""Compiled kernels of the arm's control step (needs ``numba``, a dependency; without it the numpy paths run).

Why: a control step evaluates about ten collision pairs. Each pair is one ``mj_geomDistance``
and one ``mj_jac`` (a fraction of a microsecond in C), but from Python each call, and each small
numpy operation that assembles the rows around them, costs about as much again in interpreter
and binding overhead; together that was most of the barrier phase. The kernels here do the
whole per-step work of :meth:`CollisionBarriers.near <isf_robot.arm.collision.CollisionBarriers.near>`
(broad phase or the run's joint-coherence bounds, narrow phase, ``h``, the unit normals and
``dh/dq``) and of the safety monitor's physics sub-steps in one compiled call each, calling
MuJoCo's C functions ``mj_geomDistance`` and ``mj_jac`` directly: from the ``libmujoco`` the
``mujoco`` package ships, resolved by symbol name, on the addresses of the very ``MjModel`` and
``MjData`` the Python bindings hold (``_address``).

One source: the kernels are plain functions compiled by :func:`~isf_robot.core.jit.compiled`
(numba's cache keyed on every source file of this folder); what they compute they take from the
:func:`~isf_robot.core.jit.formula` functions that the numpy paths call too (the rows in
:mod:`isf_robot.arm.narrow` and :mod:`isf_robot.arm.joint_limits`, the control laws in
:mod:`isf_robot.arm.tracking_law` and :mod:`isf_robot.arm.reaching_law`). The two paths agree to
rounding (``tests/arm/test_kernels.py`` and ``test_step_kernels.py``: 1e-12 relative, with an
absolute floor). Pairs whose witness points coincide (``|dist| < 1e-9``) are left to the numpy path.
The collision kernel takes its tables as one array of their addresses (``_kernels_jit.near_packed_key``):
a numba call costs about 0.1 us per 1-D and 0.6 us per 2-D array argument, which for 31 arguments
was more than the kernel's work.

The nominal and act phases (:func:`step_kernels`, ``_kernels_step.py``): the tracker's ``apply``
(``mj_mulM``), its ``command`` with the tracking error, a sub-step's safety check fused with ``apply``,
and the reaching controller's command (``mj_jacSite``, then the damped least squares, the speed cap
and the rate limit), each one call.

The torque level's barrier phase (:func:`second_order_kernels`, ``_second_order_jit.py``): the difference of
``phi`` at ``(q + eps q_dot, t + eps)``, with the kinematics and the collision kernel at the shifted state, and the
``psi`` rows' Lie data, in one call; and the ``psi`` of the torque rollout's points. Its sense phase: the dynamics'
terms (:func:`dynamics_kernel`, ``_dynamics_jit.py``).

Without numba, or with ``ISF_ROBOT_JIT=0`` in the environment, :func:`near_kernel` and
:func:`step_kernels` return ``None`` and the numpy paths run. Under ``ISF_ROBOT_JIT=cached`` each getter
returns its kernels only where numba's cache holds every one of them (the rest run as written). The first
use compiles the kernels (a few seconds; cached in ``__pycache__`` for later processes).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from isf_robot.core.jit import compiled, jit_enabled
from isf_robot.core.jit import compiled_here as jit_compiled_here
from isf_robot.core.passes import core_kernels

__all__ = ["available", "compiled_here", "dynamics_kernel", "monitor_kernel", "near_kernel", "rollout_kernels",
           "second_order_kernels", "step_kernels"]

_STATE: dict[str, Any] = {}


def _build() -> dict[str, Callable[..., Any]] | None:
    """Compile (or load from the cache) the kernels; ``None`` when numba or libmujoco is missing."""
    if not jit_enabled():
        return None
    try:
        from . import _dynamics_jit as kdyn
        from . import _kernels_jit as kj
        from . import _kernels_step as ks
        from . import _rollout_jit as kr
        from . import _second_order_jit as k2
    except ImportError:
        return None
    fns = {"near_packed_key": kj.near_packed_key, "monitor": kj.monitor, "track_apply": ks.track_apply,
           "track_step": ks.track_step, "reach": ks.reach, "monitor_apply": ks.monitor_apply,
           "euler_step": kr.euler_step, "closed_loop_points": kr.closed_loop_points, "phi_rate": k2.phi_rate,
           "psi_tick": k2.psi_tick, "psi_points": k2.psi_points,
           "dynamics_terms": kdyn.dynamics_terms}
    return {name: compiled(fn) for name, fn in fns.items()}


def _kernels() -> dict[str, Callable[..., Any]] | None:
    key = os.environ.get("ISF_ROBOT_JIT", "1")
    if _STATE.get("key") != key:
        _STATE["key"], _STATE["kernels"] = key, _build()
    return _STATE["kernels"]


def _group(*names: str) -> tuple[Callable[..., Any], ...] | None:
    """The kernels ``names``, or ``None`` when they are off or (``ISF_ROBOT_JIT=cached``) one is not compiled."""
    k = _kernels()
    if k is None:
        return None
    got = tuple(k[name] for name in names)
    return got if all(hasattr(fn, "py_func") for fn in got) else None  # (a numba dispatcher, not the function)


def compiled_here() -> tuple[int, int]:
    """How many kernels of an arm run numba's cache already holds for this machine: ``(held, kernels)``.

    ``(0, n)`` before the first run after an install (which compiles them); ``(0, 0)`` when the
    kernels are off or absent, or the cache cannot be read.
    """
    k = _kernels()
    if k is None:
        return 0, 0
    return jit_compiled_here((*k.values(), *core_kernels()))


def available() -> bool:
    """Whether the compiled kernels are in use (numba importable, ``ISF_ROBOT_JIT`` not ``0``)."""
    return _kernels() is not None


def near_kernel() -> Callable[..., Any] | None:
    """The compiled narrow phase of :meth:`CollisionBarriers.near` (``None``: use numpy).

    Its tables as addresses, returning also the key of the set of near pairs (``_kernels_jit.near_packed_key``).
    """
    k = _group("near_packed_key")
    return None if k is None else k[0]


def second_order_kernels() -> tuple[Callable[..., Any], Callable[..., Any], Callable[..., Any]] | None:
    """The compiled difference of the torque level's ``phi``, its ``psi`` rows and its rollout's (``None``: numpy).

    ``(phi_rate, psi_tick, psi_points)`` of ``_second_order_jit``.
    """
    return _group("phi_rate", "psi_tick", "psi_points")  # type: ignore[return-value]


def dynamics_kernel() -> Callable[..., Any] | None:
    """The compiled terms of :meth:`ArmDynamics.terms <isf_robot.arm.dynamics.ArmDynamics.terms>` (``None``: bindings).

    ``_dynamics_jit.dynamics_terms``: ``mj_fullM``, the free force and ``mj_solveM`` in one call.
    """
    k = _group("dynamics_terms")
    return None if k is None else k[0]


def monitor_kernel() -> Callable[..., Any] | None:
    """The compiled sub-step check of :meth:`SafetyMonitor.substep` (``None``: use Python)."""
    k = _group("monitor")
    return None if k is None else k[0]


def step_kernels(n: int) -> dict[str, Any] | None:
    """The compiled kernels of the act and nominal phases for an arm of ``n`` joints (``None``: numpy).

    Keys: ``track_apply`` and ``track_step`` (:class:`~isf_robot.arm.lowlevel.VelocityTracker`),
    ``monitor_apply`` (a sub-step's safety check and the tracker's apply in one call), ``reach``
    (:class:`~isf_robot.arm.nominal.ReachingController`).
    """
    names = ("track_apply", "track_step", "monitor_apply", "reach")
    k = _group(*names)
    return None if k is None else dict(zip(names, k))


def rollout_kernels() -> tuple[Callable[..., Any], Callable[..., Any]] | None:
    """The compiled Euler step and whole-rollout kernels of the rollouts.

    ``(euler_step, closed_loop_points)``: the points of :class:`~isf_robot.arm.rollout.NominalRollout` and of
    :class:`~isf_robot.arm.torque_rollout.TorqueRollout`, one kernel for both. ``None``: the numpy path.
    """
    return _group("euler_step", "closed_loop_points")  # type: ignore[return-value]

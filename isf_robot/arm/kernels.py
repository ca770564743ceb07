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

Same answers: the kernels make the same floating-point operations in the same order as the
numpy path of :mod:`isf_robot.arm.narrow` (``h = dist - margin``; ``n = (p_1 - p_2) (1/dist)``;
``dh/dq_c = ((0 + n_0 J_0c) + n_1 J_1c) + n_2 J_2c``, the written order of
:func:`isf_robot.core.sums.combine3`, signed zeros included; the joint rows ``sign q + offset``), so the rows are
equal bit for bit (``tests/arm/test_kernels.py`` checks it at random states and along runs). The
broad phase and the coherence bounds only choose which pairs reach the narrow phase; both are
conservative, so the rows are the same whichever way they round.
Pairs whose witness points coincide (``|dist| < 1e-9``) are left to the numpy path. The row norms
``|dh/dq|`` and the mocap obstacles' ``dh/dt`` are added in one written order too (the numpy side in
:mod:`isf_robot.core.sums`: numpy's own ``einsum`` and BLAS products add in an order that depends on
the CPU, so no kernel could follow them on every machine). The kernel takes its tables as one array of their addresses
(``_kernels_jit.near_packed``): a numba call costs about 0.1 us per 1-D and 0.6 us per 2-D array
argument, which for 31 arguments was more than the kernel's work.

The nominal and act phases (:func:`step_kernels`, ``_kernels_step.py``): the tracker's ``apply``
(``mj_mulM``), its ``command`` with the tracking error, a sub-step's safety check fused with ``apply``,
and the reaching controller's damped least squares (``mj_jacSite``, ``mju_cholFactor``/``Solve``, the
speed cap and the rate limit), each one call, the same operations in the same order as their numpy
code (its small products in :mod:`isf_robot.core.sums`' order).

Without numba, or with ``ISF_ROBOT_JIT=0`` in the environment, :func:`near_kernel` and
:func:`step_kernels` return ``None`` and the numpy paths run. The first use compiles the kernels (a few
seconds; cached in ``__pycache__`` for later processes).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from isf_robot.core.filter_base import core_kernels
from isf_robot.core.jit import compiled_here as jit_compiled_here
from isf_robot.core.jit import jit_enabled

__all__ = ["available", "compiled_here", "monitor_kernel", "near_kernel", "step_kernels"]

_STATE: dict[str, Any] = {}


def _build() -> dict[str, Callable[..., Any]] | None:
    """Compile (or load from the cache) the kernels; ``None`` when numba or libmujoco is missing."""
    if not jit_enabled():
        return None
    try:
        from . import _kernels_jit as kj
        from . import _kernels_step as ks
    except ImportError:
        return None
    return {"near": kj.near, "near_packed": kj.near_packed, "near_packed_key": kj.near_packed_key,
            "monitor": kj.monitor,
            "track_apply": ks.track_apply, "track_step": ks.track_step, "reach": ks.reach,
            "monitor_apply": ks.monitor_apply}


def _kernels() -> dict[str, Callable[..., Any]] | None:
    key = os.environ.get("ISF_ROBOT_JIT", "1")
    if _STATE.get("key") != key:
        _STATE["key"], _STATE["kernels"] = key, _build()
    return _STATE["kernels"]


def compiled_here() -> tuple[int, int]:
    """How many kernels of an arm run numba's cache already holds for this machine: ``(held, kernels)``.

    ``(0, n)`` before the first run after an install (which compiles them); ``(0, 0)`` when the
    kernels are off or absent, or the cache cannot be read.
    """
    if _kernels() is None:
        return 0, 0
    try:
        from . import _kernels_jit, _kernels_step, _rollout_jit
    except ImportError:
        return 0, 0
    return jit_compiled_here((_kernels_jit, _kernels_step, _rollout_jit, *core_kernels()))


def available() -> bool:
    """Whether the compiled kernels are in use (numba importable, ``ISF_ROBOT_JIT`` not ``0``)."""
    return _kernels() is not None


def near_kernel(packed: bool = False) -> Callable[..., Any] | None:
    """The compiled narrow phase of :meth:`CollisionBarriers.near` (``None``: use numpy).

    ``packed``: the same with its tables as addresses, returning also the key of the set of near pairs
    (``_kernels_jit.near_packed_key``, cheaper to call).
    """
    k = _kernels()
    return None if k is None else k["near_packed_key" if packed else "near"]


def monitor_kernel() -> Callable[..., Any] | None:
    """The compiled sub-step check of :meth:`SafetyMonitor.substep` (``None``: use Python)."""
    k = _kernels()
    return None if k is None else k["monitor"]


def step_kernels(n: int) -> dict[str, Any] | None:
    """The compiled kernels of the act and nominal phases for an arm of ``n`` joints (``None``: numpy).

    Keys: ``track_apply`` and ``track_step`` (:class:`~isf_robot.arm.lowlevel.VelocityTracker`),
    ``monitor_apply`` (a sub-step's safety check and the tracker's apply in one call), ``reach``
    (:class:`~isf_robot.arm.nominal.ReachingController`).
    """
    k = _kernels()
    if k is None:
        return None
    return {"track_apply": k["track_apply"], "track_step": k["track_step"], "monitor_apply": k["monitor_apply"],
            "reach": k["reach"]}

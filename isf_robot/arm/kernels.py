"""Compiled kernels of the arm's control step (optional: needs ``numba``, the ``fast`` extra).

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
``dh/dq_c = ((0 + n_0 J_0c) + n_1 J_1c) + n_2 J_2c``, the order of numpy's product of a (1, 3)
row by a (3, n) block, signed zeros included; the joint rows ``sign q + offset``), so the rows are
equal bit for bit (``tests/arm/test_kernels.py`` checks it at random states and along runs). The
broad phase and the coherence bounds only choose which pairs reach the narrow phase; both are
conservative, so the rows are the same whichever way they round.
Pairs whose witness points coincide (``|dist| < 1e-9``) are left to the numpy path. The row norms
``|dh/dq|`` and the mocap obstacles' ``dh/dt`` are summed in the order numpy's einsum uses on this
machine, found and checked once against numpy (:func:`norm_lanes`, :func:`dot3_lanes`); where no order
matches, numpy computes them. The kernel takes its tables as one array of their addresses
(``_kernels_jit.near_packed``): a numba call costs about 0.1 us per 1-D and 0.6 us per 2-D array
argument, which for 31 arguments was more than the kernel's work.

The nominal and act phases (:func:`step_kernels`, ``_kernels_step.py``): the tracker's ``apply``
(``mj_mulM``), its ``command`` with the tracking error, a sub-step's safety check fused with ``apply``,
and the reaching controller's damped least squares (``mj_jacSite``, ``mju_cholFactor``/``Solve``, the
speed cap and the rate limit), each one call, the same operations in the same order as their numpy
code; the small BLAS products of the controller and the tracking error are checked against numpy
first (:func:`step_kernels`).

Without numba, or with ``ISF_ROBOT_JIT=0`` in the environment, :func:`near_kernel` and
:func:`step_kernels` return ``None`` and the numpy paths run. The first use compiles the kernels (a few
seconds; cached in ``__pycache__`` for later processes).
"""

from __future__ import annotations

import glob
import os
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

__all__ = ["available", "dot3_lanes", "monitor_kernel", "near_kernel", "norm_lanes", "step_kernels"]

_STATE: dict[str, Any] = {}


def _library() -> str | None:
    """Path of the MuJoCo shared library the ``mujoco`` package loads (``None``: not found)."""
    folder = os.path.dirname(mujoco.__file__)
    for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll"):
        found = sorted(glob.glob(os.path.join(folder, pattern)))
        if found:
            return found[0]
    return None


def _build() -> dict[str, Callable[..., Any]] | None:
    """Compile (or load from the cache) the kernels; ``None`` when numba or libmujoco is missing."""
    if os.environ.get("ISF_ROBOT_JIT", "1").strip().lower() in ("0", "false", "no", "off"):
        return None
    try:
        from . import _kernels_jit as kj
        from . import _kernels_step as ks
    except ImportError:
        return None
    return {"near": kj.near, "near_packed": kj.near_packed, "near_packed_key": kj.near_packed_key,
            "monitor": kj.monitor, "norms": kj.norms, "dots3": kj.dots3,
            "track_apply": ks.track_apply, "track_step": ks.track_step, "reach": ks.reach,
            "monitor_apply": ks.monitor_apply,
            "blas_orders": ks.blas_orders}


def _kernels() -> dict[str, Callable[..., Any]] | None:
    key = os.environ.get("ISF_ROBOT_JIT", "1")
    if _STATE.get("key") != key:
        _STATE["key"], _STATE["kernels"] = key, _build()
    return _STATE["kernels"]


def norm_lanes(n: int) -> int:
    """How numpy's ``sqrt(einsum("ij,ij->i", g, g))`` sums a row of ``n`` squares on this machine.

    Its SIMD loop keeps several partial sums (lanes), which depends on the CPU and the numpy
    build. Candidates: 1 (in order), 2, 4, 8 interleaved lanes added in order, -4 (four lanes added
    pairwise). Each is tried on 4000 random rows (scales 1e-3..1e3, some zeros) and taken only when
    every norm equals numpy's bit for bit; 0 when none does (the caller then uses numpy).
    """
    k = _kernels()
    if k is None:
        return 0
    cache = _STATE.setdefault("lanes", {})
    if n not in cache:
        rng = np.random.default_rng(12345)
        g = rng.normal(size=(4000, n)) * 10.0 ** rng.uniform(-3, 3, size=(4000, n))
        g[rng.random(g.shape) < 0.2] = 0.0
        want = np.sqrt(np.einsum("ij,ij->i", g, g))
        cache[n] = next((lanes for lanes in (2, 1, 4, -4, 8)
                         if k["norms"](g, lanes).tobytes() == want.tobytes()), 0)
    return int(cache[n])


def dot3_lanes() -> int:
    """How numpy's ``einsum("ij,ij->i", a, b)`` sums rows of 3 products on this machine (0: no kernel order matches).

    Candidates 2 (two interleaved lanes from 0, as :func:`norm_lanes` finds for squares) and 1 (in order), each
    tried on batches of 1..12 and 4000 random rows (scales 1e-3..1e3, some zeros); the kernel's ``dh/dt`` of
    mocap obstacles is used only with a match (otherwise numpy computes it).
    """
    k = _kernels()
    if k is None:
        return 0
    if "dot3" not in _STATE:
        rng = np.random.default_rng(54321)
        batches = []
        for size in (*range(1, 13), 4000):
            a, b = (rng.normal(size=(size, 3)) * 10.0 ** rng.uniform(-3, 3, size=(size, 3)) for _ in range(2))
            a[rng.random(a.shape) < 0.2] = 0.0
            batches.append((a, b, np.einsum("ij,ij->i", a, b)))
        _STATE["dot3"] = next((lanes for lanes in (2, 1) if all(
            k["dots3"](a, b, lanes).tobytes() == want.tobytes() for a, b, want in batches)), 0)
    return int(_STATE["dot3"])


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


def _blas_orders(n: int) -> tuple[bool, bool]:
    """Whether the step kernels' small products equal numpy's on this machine, bit for bit.

    ``(dot, reach)``: ``dot`` for the tracking error's ``e.dot(e)`` of ``n``; ``reach`` for the reaching
    controller's ``err.dot(err)`` of 3, ``np.dot(J, J.T)`` and ``y.dot(J)`` of a (3, ``n``) Jacobian (the
    calls :class:`~isf_robot.arm.nominal.ReachingController` makes). Each is tried on 2000 random cases
    (scales 1e-3..1e3, some zeros), like :func:`norm_lanes`.
    """
    k = _kernels()
    if k is None:
        return False, False
    cache = _STATE.setdefault("blas", {})
    if n not in cache:
        rng = np.random.default_rng(2468)
        m = 2000

        def draw(*shape: int) -> np.ndarray:
            x = rng.normal(size=shape) * 10.0 ** rng.uniform(-3, 3, size=shape)
            x[rng.random(shape) < 0.1] = 0.0
            return x

        x3, xn, jac, y = draw(m, 3), draw(m, n), draw(m, 3, n), draw(m, 3)
        d3, dn, syrk, gemv = np.empty(m), np.empty(m), np.empty((m, 3, 3)), np.empty((m, n))
        k["blas_orders"](x3, jac, y, d3, syrk, gemv)
        k["blas_orders"](xn, jac[:1], y[:1], dn, syrk[:1], gemv[:1])
        a = np.zeros((3, 3))
        ok_dot = all(float(xn[i].dot(xn[i])) == dn[i] for i in range(m))
        ok_reach = all(float(x3[i].dot(x3[i])) == d3[i] for i in range(m))
        for i in range(m):
            if not ok_reach:
                break
            ji = np.ascontiguousarray(jac[i])
            np.dot(ji, ji.T, out=a)
            ok_reach = a.tobytes() == syrk[i].tobytes() and y[i].dot(ji).tobytes() == gemv[i].tobytes()
        cache[n] = (ok_dot, ok_reach)
    return cache[n]


def step_kernels(n: int) -> dict[str, Any] | None:
    """The compiled kernels of the act and nominal phases for an arm of ``n`` joints (``None``: numpy).

    Keys: ``track_apply`` and ``track_step`` (:class:`~isf_robot.arm.lowlevel.VelocityTracker`),
    ``monitor_apply`` (a sub-step's safety check and the tracker's apply in one call), ``reach``
    (:class:`~isf_robot.arm.nominal.ReachingController`, ``None`` where this machine's BLAS sums its
    products in another order than the kernel), ``dot``: whether ``track_step``'s tracking error is
    numpy's to the bit.
    """
    k = _kernels()
    if k is None:
        return None
    ok_dot, ok_reach = _blas_orders(int(n))
    return {"track_apply": k["track_apply"], "track_step": k["track_step"], "monitor_apply": k["monitor_apply"],
            "reach": k["reach"] if ok_reach else None, "dot": ok_dot}

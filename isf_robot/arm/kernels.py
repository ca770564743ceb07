"""Compiled kernels of the barrier phase (optional: needs ``numba``, the ``fast`` extra).

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
``|dh/dq|`` are summed in the order numpy's einsum uses on this machine, found and checked once
against numpy (:func:`norm_lanes`); where no order matches, numpy computes them.

Without numba, or with ``ISF_ROBOT_JIT=0`` in the environment, :func:`near_kernel` returns
``None`` and the numpy path runs. The first use compiles the kernels (a few seconds; cached in
``__pycache__`` for later processes).
"""

from __future__ import annotations

import glob
import math
import os
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

__all__ = ["available", "monitor_kernel", "near_kernel", "norm_lanes"]

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
    path = _library()
    if path is None:
        return None
    try:
        import llvmlite.binding as llvm
        from numba import njit, types
    except ImportError:
        return None
    llvm.load_library_permanently(path)
    ptr, i32, f64 = types.intp, types.int32, types.float64
    # mjtNum mj_geomDistance(const mjModel*, mjData*, int geom1, int geom2, mjtNum distmax, mjtNum fromto[6])
    geom_distance = types.ExternalFunction("mj_geomDistance", f64(ptr, ptr, i32, i32, f64, ptr))
    # void mj_jac(const mjModel*, const mjData*, mjtNum* jacp, mjtNum* jacr, const mjtNum point[3], int body)
    jac = types.ExternalFunction("mj_jac", types.void(ptr, ptr, ptr, ptr, ptr, i32))

    @njit(cache=True, nogil=True)
    def row_norm(g, k, lanes):  # pragma: no cover (compiled)
        """|g[k]| summed the way :func:`norm_lanes` found numpy's einsum does it (``lanes``)."""
        n = g.shape[1]
        if lanes == 1:
            s = 0.0
            for c in range(n):
                s += g[k, c] * g[k, c]
            return np.sqrt(s)
        if lanes == 2:
            a0 = 0.0
            a1 = 0.0
            for c in range(0, n - 1, 2):
                a0 += g[k, c] * g[k, c]
                a1 += g[k, c + 1] * g[k, c + 1]
            if n % 2:
                a0 += g[k, n - 1] * g[k, n - 1]
            return np.sqrt(a0 + a1)
        width = abs(lanes)
        acc = np.zeros(width)
        for c in range(n):
            acc[c % width] += g[k, c] * g[k, c]
        if lanes == -4:
            return np.sqrt((acc[0] + acc[2]) + (acc[1] + acc[3]))
        s = acc[0]
        for lane in range(1, width):
            s += acc[lane]
        return np.sqrt(s)

    @njit(cache=True, nogil=True)
    def norms(g, lanes):  # pragma: no cover (compiled)
        out = np.empty(g.shape[0])
        for k in range(g.shape[0]):
            out[k] = row_norm(g, k, lanes)
        return out

    @njit(cache=True, nogil=True)
    def near(ma, da, qpos, xpos, live, margin, thr2, coh, lower, qprev, qstate, lever, qadr,
             cutoff, distmax, slack, eps, dof, fromto, jac1, jac2, jq, jsign, joff, jgrad, lanes,
             rows, h, g, gn, wit):  # pragma: no cover (compiled)
        """Fill rows[:j], h[:j + l], g[:j + l], gn[:j + l] (if lanes) and wit[:j] = (p1, p2, n).

        Returns (j, min h, min dist, min joint value, whether some witness points coincide).
        """
        n_live = live.shape[0]
        cand = np.empty(n_live, np.int64)
        nc = 0
        if coh:
            nu = qadr.size
            if qstate[0] != 0:
                dq = np.empty(nu)
                for u in range(nu):
                    dq[u] = abs(qpos[qadr[u]] - qprev[u])
                for r in range(n_live):
                    s = 0.0
                    for u in range(nu):
                        s += lever[r, u] * dq[u]
                    lower[r] -= s
            for u in range(nu):
                qprev[u] = qpos[qadr[u]]
            qstate[0] = 1
            for r in range(n_live):
                if lower[r] < cutoff:
                    cand[nc] = r
                    nc += 1
            dmax = distmax
        else:
            for r in range(n_live):
                a, b = live[r, 1], live[r, 2]
                dx = xpos[a, 0] - xpos[b, 0]
                dy = xpos[a, 1] - xpos[b, 1]
                dz = xpos[a, 2] - xpos[b, 2]
                if dx * dx + dy * dy + dz * dz < thr2[r]:
                    cand[nc] = r
                    nc += 1
            dmax = cutoff
        # Narrow phase: near pairs packed in rows 0, 1, ... of the scratch (a far one's row is reused).
        sel = np.empty(nc, np.int64)
        ds = np.empty(nc)
        j = 0
        for c in range(nc):
            r = cand[c]
            d = geom_distance(ma, da, np.int32(live[r, 1]), np.int32(live[r, 2]), dmax,
                              fromto[j].ctypes.data)
            if coh:
                lower[r] = d - slack
            if d < cutoff:
                sel[j] = r
                ds[j] = d
                j += 1
        ndof = dof.size
        nj = jq.size
        jmin = math.inf
        for i in range(nj):  # the joint-limit rows after the pairs'
            hj = jsign[i] * qpos[jq[i]] + joff[i]
            h[j + i] = hj
            jmin = min(jmin, hj)
            for c in range(ndof):
                g[j + i, c] = jgrad[i, c]
        hmin = math.inf
        dmin = math.inf
        touching = False
        for k in range(j):
            r = sel[k]
            d = ds[k]
            rows[k] = live[r, 0]
            hk = d - margin[r]
            h[k] = hk
            hmin = min(hmin, hk)
            dmin = min(dmin, d)
            for e in range(3):
                wit[k, 0, e] = fromto[k, e]
                wit[k, 1, e] = fromto[k, 3 + e]
            if -eps < d < eps:
                touching = True
                continue
            inv = 1.0 / d
            n0 = (fromto[k, 0] - fromto[k, 3]) * inv
            n1 = (fromto[k, 1] - fromto[k, 4]) * inv
            n2 = (fromto[k, 2] - fromto[k, 5]) * inv
            wit[k, 2, 0], wit[k, 2, 1], wit[k, 2, 2] = n0, n1, n2
            jac(ma, da, jac1.ctypes.data, 0, fromto[k].ctypes.data, np.int32(live[r, 3]))
            for c in range(ndof):
                col = dof[c]
                g[k, c] = 0.0 + n0 * jac1[0, col] + n1 * jac1[1, col] + n2 * jac1[2, col]
            if live[r, 5] != 0:
                jac(ma, da, jac2.ctypes.data, 0, fromto[k, 3:].ctypes.data, np.int32(live[r, 4]))
                for c in range(ndof):
                    col = dof[c]
                    g[k, c] = g[k, c] - (0.0 + n0 * jac2[0, col] + n1 * jac2[1, col] + n2 * jac2[2, col])
        if lanes != 0:
            for k in range(j + nj):
                gn[k] = row_norm(g, k, lanes)
        return j, hmin, dmin, jmin, touching

    @njit(cache=True, nogil=True)
    def monitor(ma, da, rows, g1, g2, margin, thresh, bound):  # pragma: no cover (compiled)
        step_h = math.inf
        step_d = math.inf
        for t in range(rows.size):
            i = rows[t]
            cap = max(thresh + margin[i], bound) + 1e-6
            d = geom_distance(ma, da, np.int32(g1[i]), np.int32(g2[i]), cap, 0)
            if d - margin[i] < step_h:
                step_h = d - margin[i]
            if d < step_d:
                step_d = d
        return step_h, step_d

    return {"near": near, "monitor": monitor, "norms": norms}


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


def available() -> bool:
    """Whether the compiled kernels are in use (numba importable, ``ISF_ROBOT_JIT`` not ``0``)."""
    return _kernels() is not None


def near_kernel() -> Callable[..., Any] | None:
    """The compiled narrow phase of :meth:`CollisionBarriers.near` (``None``: use numpy)."""
    k = _kernels()
    return None if k is None else k["near"]


def monitor_kernel() -> Callable[..., Any] | None:
    """The compiled sub-step check of :meth:`SafetyMonitor.substep` (``None``: use Python)."""
    k = _kernels()
    return None if k is None else k["monitor"]

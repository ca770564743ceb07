"""A run's numbers do not depend on the BLAS kernels this machine's OpenBLAS picks.

numpy's OpenBLAS chooses its kernels by CPU (``DYNAMIC_ARCH``); its products add in other orders
(and with or without fused multiply-adds) from one kernel to another, which once gave other last
bits on an Intel Xeon than on an AMD EPYC and failed the compiled kernels' bit-for-bit tests there.
The step's small products are now made in one written order (``isf_robot/core/sums.py``), so a run
gives the same numbers under any kernel. Here the same 1 s panda_pole isf episode (d_bar calibrated,
the predictive trigger's rollouts, the few-row and one-row steps, the metrics) runs in one process per
kernel, ``OPENBLAS_CORETYPE=Nehalem`` and ``Haswell`` (SSE without FMA, AVX2 with FMA: every x86-64
CPU runs them) and, where the CPU has AVX-512, ``SkylakeX`` (its dot product adds in another order
again), and every step's rows and command and the run's results must be equal. The test first checks
that the kernels do give other bits for plain numpy products, so it can fail.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                                reason="OpenBLAS's x86-64 kernel names")

_PROBE = """
import hashlib, numpy as np
rng = np.random.default_rng(1)
a, b = rng.normal(size=(2000, 7)), rng.normal(size=7)
print(hashlib.sha256((a @ b).tobytes() + np.array([x @ x for x in a]).tobytes()).hexdigest())
"""

_RUN = """
import hashlib, json, numpy as np
from isf_robot.arm import load_scene
from isf_robot.arm.params import resolve_params
from isf_robot.arm.sim import ArmSimulation
scene = load_scene("panda_pole")
sim = ArmSimulation(scene, "isf", seed=0, params=resolve_params(scene), control_period=0.001)
h = hashlib.sha256()
step_lie = sim.strategy.step_lie
def hashed(t, lie, u_nom, *a, **k):
    s = step_lie(t, lie, u_nom, *a, **k)
    for x in (lie.h, lie.lf, lie.lg, lie.grad_norm, u_nom, s.u):
        h.update(np.ascontiguousarray(x, dtype=float).tobytes())
    return s
sim.strategy.step_lie = hashed
d = sim.run(1.0).as_dict()
for key in ("wall_s", "timings", "qp_time_median_us", "solver_time_median_us"):
    d.pop(key, None)
print(json.dumps({"steps": h.hexdigest(), "result": {k: repr(v) for k, v in d.items()}}, sort_keys=True))
"""


def _run(code: str, core: str) -> str:
    env = {**os.environ, "OPENBLAS_CORETYPE": core, "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip().splitlines()[-1]


def _cores() -> list[str]:
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            avx512 = " avx512f" in f.read()
    except OSError:
        avx512 = False
    return ["Nehalem", "Haswell"] + (["SkylakeX"] if avx512 else [])


def test_a_run_gives_the_same_numbers_under_other_blas_kernels() -> None:
    cores = _cores()
    if len({_run(_PROBE, core) for core in cores}) == 1:
        pytest.skip("OPENBLAS_CORETYPE does not change numpy's products here (not OpenBLAS, or one kernel only)")
    runs = [json.loads(_run(_RUN, core)) for core in cores]
    first = runs[0]
    assert first["result"]["control_steps"] == "1000" and float(first["result"]["duty_cycle"]) > 0  # (it acted)
    assert all(run == first for run in runs[1:]), cores

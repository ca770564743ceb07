"""The demo never waits for the compiler: on a fresh install it runs the plain path and says so; later it uses
the kernels numba's cache holds and runs the rest as written."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from isf_robot.arm import kernels
from isf_robot.cli.arm import DEMO_PLAIN_NOTICE
from isf_robot.core.jit import COMPILE_NOTICE, NOTICE_ENV

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0)")

DEMO = ["demo", "--episodes", "1", "--duration", "0.3", "--jobs", "1", "--json"]


def _cli(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    out = subprocess.run([sys.executable, "-m", "isf_robot.cli", *args], env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    return out


def _held(env: dict[str, str]) -> tuple[int, int]:
    code = "from isf_robot.arm import kernels; print(*kernels.compiled_here())"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300, check=True)
    held, count = map(int, out.stdout.split())
    return held, count


def test_the_demo_runs_the_plain_path_until_a_run_has_compiled_the_kernels(tmp_path) -> None:  # type: ignore[no-untyped-def]
    tmp = tmp_path / "tmp"  # (the commands' own temporary folder: where a command's notice marker lives while it runs)
    tmp.mkdir()
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "ISF_ROBOT_JIT": "1", "TMPDIR": str(tmp)}
    env.pop(NOTICE_ENV, None)
    held, count = _held(env)
    assert count >= 10 and held == 0  # (a fresh install: nothing compiled)

    cold = _cli(DEMO, env)
    assert DEMO_PLAIN_NOTICE in cold.stderr
    assert COMPILE_NOTICE not in cold.stderr  # (nothing compiled: the plain path ran)
    assert _held(env) == (0, count)
    assert set(json.loads(cold.stdout)["results"]) >= {"nominal", "cbf", "isf"}

    # (a run without a filter compiles the kernels every strategy steps with, the arm's, and not the filters':
    # the warm demo then mixes compiled and written code in each of its strategies)
    run_args = ["run", "--scene", "panda_pole", "--filter", "nominal", "--duration", "0.3", "--d-bar", "0.05"]
    run = _cli(run_args, env)
    assert run.stderr.count(COMPILE_NOTICE) == 1  # (a cold cache says so, once)
    held, _ = _held(env)
    assert 0 < held <= count

    warm = _cli(DEMO, env)  # (the kernels the run compiled, the rest as written: the demo compiles nothing)
    assert DEMO_PLAIN_NOTICE not in warm.stderr and COMPILE_NOTICE not in warm.stderr
    assert _held(env) == (held, count)
    cold_res, warm_res = json.loads(cold.stdout)["results"], json.loads(warm.stdout)["results"]
    assert warm_res.keys() == cold_res.keys()
    for name, res in cold_res.items():  # (the same numbers, whichever kernels ran)
        assert warm_res[name]["qp_solves"] == res["qp_solves"], name
        assert warm_res[name]["duty_cycle"] == pytest.approx(res["duty_cycle"], rel=1e-9, abs=1e-12), name
    again = _cli(run_args, env)  # (a warm cache says nothing)
    assert COMPILE_NOTICE not in again.stderr
    assert not list(tmp.glob("*compile-notice*"))  # (each command removed its marker when it ended)

"""The demo on a machine whose kernels are not compiled yet: it runs the plain path at once and says so."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from isf_robot.arm import kernels
from isf_robot.cli.arm import DEMO_PLAIN_NOTICE
from isf_robot.core.jit import COMPILE_NOTICE

pytestmark = pytest.mark.skipif(not kernels.available(), reason="compiled kernels off (ISF_ROBOT_JIT=0)")


def test_after_a_run_the_kernels_are_held_by_the_cache() -> None:
    from isf_robot.arm import ArmSimulation, load_scene

    scene = load_scene("panda_pole")
    for strategy in ("cbf", "isf"):  # (every kernel of an arm run: compiled, or loaded, here)
        ArmSimulation(scene, strategy, seed=0, d_bar=0.05).run(0.3)
    assert kernels.compiled_here()


def test_a_cold_cache_makes_the_demo_run_the_plain_path_without_compiling(tmp_path) -> None:  # type: ignore[no-untyped-def]
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "empty"), "ISF_ROBOT_JIT": "1"}
    cmd = [sys.executable, "-m", "isf_robot.cli", "demo", "--episodes", "1", "--duration", "0.3", "--jobs", "1",
           "--json"]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert DEMO_PLAIN_NOTICE in out.stderr
    assert COMPILE_NOTICE not in out.stderr  # (nothing compiled: the plain path ran)
    assert not list((tmp_path / "empty").rglob("*.nbi"))
    result = json.loads(out.stdout)
    assert set(result["results"]) >= {"nominal", "cbf", "isf"}

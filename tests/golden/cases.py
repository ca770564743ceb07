"""The command lines pinned by golden outputs, and how their JSON is compared.

Arm: ``isf-robot run --json`` for each Panda scene x strategy at a fixed seed (4 s episodes, the
scene's own control period, ``d_bar`` calibrated as a user would get it). Satellite:
``isf-satellite run --trigger greedy --json`` at a fixed seed over 200 h.
"""

from __future__ import annotations

import contextlib
import io
import json
from typing import Any

ARM_SCENES = ("panda_pole", "panda_shelf", "panda_moving")
ARM_STRATEGIES = ("nominal", "cbf", "isf")

CASES: dict[str, list[str]] = {}
for _scene in ARM_SCENES:
    for _strategy in ARM_STRATEGIES:
        CASES[f"arm-{_scene}-{_strategy}"] = [
            "isf-robot", "run", "--scene", _scene, "--filter", _strategy, "--seed", "3",
            "--duration", "4", "--json"]
CASES["satellite-greedy"] = ["isf-satellite", "run", "--trigger", "greedy", "--hours", "200",
                             "--seed", "2", "--json", "--quiet"]

# Fields that measure the machine, not the behaviour: never compared.
VOLATILE = frozenset({"wall_s", "timings", "qp_time_median_us", "proxqp_time_median_us", "solver_time_median_us",
                      "nfev"})


def run_case(argv: list[str]) -> dict[str, Any]:
    """Run one command line in this process and return its parsed JSON output."""
    if argv[0] == "isf-robot":
        from isf_robot.cli import main
    else:
        from satellite.cli import main
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(argv[1:])
    assert code == 0, f"{' '.join(argv)} exited {code}"
    return json.loads(buf.getvalue())


def stable(out: dict[str, Any]) -> dict[str, Any]:
    """The output without the machine-dependent fields."""
    return {k: v for k, v in out.items() if k not in VOLATILE}

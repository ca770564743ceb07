"""isf-robot sweep on Ray: the same numbers as local processes, Ctrl-C keeps what finished, a clear
error without the extra. Ray is in the ``test`` extra, so CI runs these; a checkout without it skips
them, except under ``CI`` where a missing Ray fails instead of passing quietly."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from isf_robot.arm.compare import SceneSpec
from isf_robot.arm.sweep import SweepPoint, run_sweep
from isf_robot.cli import main
from isf_robot.paths import models_dir

pytestmark = pytest.mark.usefixtures("arm_compiled", "outside_checkout")  # (tests/conftest.py)

try:
    import ray  # noqa: F401

    HAVE_RAY = True
except ImportError:
    HAVE_RAY = False

needs_ray = pytest.mark.skipif(not HAVE_RAY and not os.environ.get("CI"),
                               reason="ray not installed (pip install '.[ray]'); CI installs it with the test extra")

_MACHINE = ("wall_s", "timings", "solver_time_median_us", "qp_time_median_us", "qp_time_max_us")


def _numbers(sweep):
    """The sweep without the machine-dependent wall times."""
    sweep = json.loads(json.dumps(sweep))
    for sc in sweep["scenes"]:
        for row in sc["points"]:
            row.pop("wall_s")
            for run in row["runs"]:
                for k in [k for k in run if k in _MACHINE or k.endswith("_us")]:
                    run.pop(k)
    return sweep


@needs_ray
@pytest.mark.usefixtures("local_ray")  # (tests/conftest.py: one local instance, joined by run_tasks)
def test_sweep_on_local_ray_equals_local_processes():
    pts = [SweepPoint("cbf", {}), SweepPoint("isf", {"c": 0.1, "blend": 0.02})]
    args = dict(duration=0.6, d_bar=0.05)
    seen = []
    files = SceneSpec(model=str(models_dir() / "planar.xml"), config=str(models_dir() / "planar.toml"))
    on_ray = run_sweep([files], pts, [0, 1], jobs=2, backend="ray",  # a user's own files, as --model/--config
                       progress=lambda done, total, task, r: seen.append((done, total)), **args)
    local = run_sweep([SceneSpec(name="planar")], pts, [0, 1], jobs=2, **args)
    assert sorted(seen) == [(i, 4) for i in range(1, 5)]
    assert _numbers(on_ray) == _numbers(local)
    runs = [run for row in on_ray["scenes"][0]["points"] for run in row["runs"]]
    assert len(runs) == 4 and all(r["control_steps"] == 300 for r in runs)
    assert len({(r["filter"], r["seed"], r["intervention"]) for r in runs}) == 4
    assert len({r["intervention"] for r in runs}) > 1  # not one answer copied everywhere


@needs_ray
@pytest.mark.parametrize(("sig", "group", "code", "word"), [(signal.SIGINT, True, 130, "interrupted"),
                                                            (signal.SIGTERM, False, 143, "terminated")])
def test_ctrl_c_on_ray_keeps_what_finished_and_leaves_nothing_behind(sig, group, code, word):
    # SIGTERM: ray.init replaces the driver's handler and ray.wait turns the handler's exception into a
    # bare KeyboardInterrupt; run_tasks must still report a SIGTERM (143, "terminated")
    argv = [sys.executable, "-m", "isf_robot.cli", "sweep", "--scenes", "planar", "--filters", "cbf", "isf",
            "--episodes", "4", "--duration", "8", "--d-bar", "0.1", "--backend", "ray", "--jobs", "2", "--json"]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    lines, t0 = [], time.monotonic()
    while time.monotonic() - t0 < 240:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        if "[1/8]" in line:
            break
    else:
        proc.kill()
    assert lines and "[1/8]" in lines[-1], "".join(lines)
    t0 = time.monotonic()
    if group:
        os.killpg(proc.pid, sig)  # a terminal's Ctrl-C: the whole process group
    else:
        proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert time.monotonic() - t0 < 20.0
    assert proc.returncode == code, err
    assert "Traceback" not in err and word in err
    doc = json.loads(out)
    assert doc["partial"] is True
    finished = sum(len(row["runs"]) for sc in doc["scenes"] for row in sc["points"])
    assert 1 <= finished < 8
    deadline = time.monotonic() + 10
    while True:  # Ray's own processes (gcs, raylet, workers) run in the command's group
        ps = subprocess.run(["ps", "-o", "stat=,args=", "-g", str(proc.pid)], capture_output=True, text=True).stdout
        live = [p for p in ps.splitlines() if p.strip() and not p.split()[0].startswith("Z")]
        if not live or time.monotonic() > deadline:
            break
        time.sleep(0.3)
    assert live == [], live


def test_ray_backend_without_ray_names_the_extra(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    code = main(["sweep", "--scenes", "planar", "--episodes", "1", "--duration", "0.1", "--d-bar", "0.05",
                 "--backend", "ray", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "pip install 'isf-robot[ray]'" in err and len(err.strip().splitlines()) == 1
    assert main(["sweep", "--scenes", "planar", "--address", "auto"]) == 2
    assert "--address goes with --backend ray" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["sweep", "--scenes", "planar", "--backend", "dask"])
    assert exc.value.code == 2 and "'processes', 'ray'" in capsys.readouterr().err

"""Signals sent to real subprocesses: Ctrl-C and SIGTERM stop the whole command quickly, keep what
finished (marked partial), leave no worker behind and no traceback; an interrupted recording
leaves the previous file byte-identical and its data under ``<name>.partial``."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = [pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals"),
              pytest.mark.usefixtures("arm_compiled")]  # (compiled before a clock starts: tests/conftest.py)

ROBOT = [sys.executable, "-m", "isf_robot.cli"]
SATELLITE = [sys.executable, "-c", "import sys; from satellite.cli import main; sys.exit(main())"]


def _start(argv: list[str]) -> subprocess.Popen[str]:
    # a new session: the test can signal the whole process group, as a terminal's Ctrl-C does
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})


def _wait_for_line(proc: subprocess.Popen[str], needle: str, timeout: float = 120.0) -> list[str]:
    """Read stderr lines until one contains ``needle`` (the command is mid-run then)."""
    assert proc.stderr is not None
    lines: list[str] = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        if needle in line:
            return lines
    proc.kill()
    raise AssertionError(f"never saw {needle!r}; stderr: {''.join(lines)}")


def _left_behind(pgid: int, timeout: float = 5.0) -> list[str]:
    """Live processes of the command's group (zombies awaiting their reaper do not count)."""
    t0 = time.monotonic()
    while True:
        out = subprocess.run(["ps", "-o", "pid=,stat=,args=", "-g", str(pgid)], capture_output=True, text=True).stdout
        live = [line for line in out.splitlines() if line.split()[1:2] and not line.split()[1].startswith("Z")]
        if not live or time.monotonic() - t0 > timeout:
            return live
        time.sleep(0.2)


@pytest.mark.parametrize(("sig", "group", "code"), [
    (signal.SIGINT, False, 130), (signal.SIGINT, True, 130), (signal.SIGTERM, False, 143)])
def test_compare_with_workers_stops_and_keeps_what_finished(sig: int, group: bool, code: int) -> None:
    proc = _start(ROBOT + ["compare", "--scene", "planar", "--episodes", "4", "--duration", "10",
                           "--filters", "nominal", "cbf", "--jobs", "2", "--d-bar", "0.1", "--json"])
    _wait_for_line(proc, "[1/8]")  # one episode finished, two workers are busy
    t0 = time.monotonic()
    if group:
        os.killpg(proc.pid, sig)
    else:
        proc.send_signal(sig)
    out, err = proc.communicate(timeout=30)
    assert time.monotonic() - t0 < 5.0
    assert proc.returncode == code, err
    assert "Traceback" not in err and ("interrupted" in err or "terminated" in err)
    doc = json.loads(out)
    assert doc["partial"] is True
    finished = sum(len(r["episodes"]) for r in doc["results"].values())
    assert 1 <= finished < 8
    assert _left_behind(proc.pid) == [], "worker or resource-tracker processes left behind"


def test_interrupted_recording_keeps_the_previous_file(tmp_path: Path) -> None:
    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"previous recording")
    proc = _start(ROBOT + ["run", "--scene", "planar", "--d-bar", "0.1", "--duration", "600", "--rrd", str(rrd)])
    time.sleep(1.0)
    while not (tmp_path / "run.rrd.partial").exists() and proc.poll() is None:
        time.sleep(0.2)
    time.sleep(2.0)  # mid-run
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and "Traceback" not in err and err.strip().endswith("interrupted")
    assert rrd.read_bytes() == b"previous recording"
    assert (tmp_path / "run.rrd.partial").stat().st_size > 0


@pytest.fixture(scope="module")
def satellite_compiled() -> None:
    """numba's cache of the satellite's compiled arcs, filled before a test starts its clock.

    A fresh clone has none: the first arc of a run compiles for ~13 s on one free core (this Intel
    Xeon; about twice that with two test workers and another load), and a Ctrl-C in that time is
    held until the compilation ends (satellite.orbit.fast_arcs.signals_deferred), so a signal sent "2 s
    after the recording opened" would wait for the compiler, not test the interrupt of a run. One
    short run of the same command fills the cache (~1.5 s when it is already there); its bound,
    600 s, only catches a hang.
    """
    done = subprocess.run(SATELLITE + ["run", "--trigger", "greedy", "--hours", "1", "--quiet"], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr


def test_signals_in_compiled_calls_act_when_the_call_returns() -> None:
    """satellite.orbit.fast_arcs.signals_deferred: the handler does not run inside the body, it runs at its end."""
    from satellite.orbit.fast_arcs import signals_deferred

    class Hit(Exception):
        pass

    def raise_hit(signum: int, frame: object) -> None:
        raise Hit(signum)

    previous = signal.signal(signal.SIGINT, raise_hit)
    try:
        reached = False
        with pytest.raises(Hit), signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # an undeferred handler would have raised by now
            reached = True
        assert reached and signal.getsignal(signal.SIGINT) is raise_hit  # the handler is back
    finally:
        signal.signal(signal.SIGINT, previous)


def test_satellite_run_interrupt_is_one_line(satellite_compiled: None) -> None:
    proc = _start(SATELLITE + ["run", "--trigger", "greedy", "--hours", "100000", "--quiet"])
    time.sleep(6.0)  # past the imports: the integration runs (its first progress line is 10000 h away)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "isf-satellite run: interrupted"


def test_interrupted_satellite_recording_keeps_the_previous_file(tmp_path: Path, satellite_compiled: None) -> None:
    rrd = tmp_path / "sat.rrd"
    rrd.write_bytes(b"previous recording")
    proc = _start(SATELLITE + ["run", "--trigger", "greedy", "--hours", "100000", "--quiet", "--rrd", str(rrd)])
    while not (tmp_path / "sat.rrd.partial").exists() and proc.poll() is None:
        time.sleep(0.2)  # the recording opens once every parameter is checked
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130 and "Traceback" not in err
    assert rrd.read_bytes() == b"previous recording"
    assert (tmp_path / "sat.rrd.partial").stat().st_size > 0


# Ctrl-C while a command line is still importing its command modules (before any handler runs):
# the process signals itself from inside the import, the way a user's early Ctrl-C lands.
_EARLY = """
import importlib, os, signal, sys
real = importlib.import_module
def interrupted_import(name, *a, **k):
    if name == {module!r}:
        os.kill(os.getpid(), signal.SIGINT)
    return real(name, *a, **k)
importlib.import_module = interrupted_import
from {cli} import main
sys.exit(main(["--help"]))
"""


@pytest.mark.parametrize(("cli", "module", "prog"), [
    ("isf_robot.cli", "isf_robot.cli.replay", "isf-robot"),
    ("satellite.cli", "satellite.cli.run", "isf-satellite")])
def test_ctrl_c_while_importing_commands_is_one_line(cli: str, module: str, prog: str) -> None:
    code = _EARLY.format(cli=cli, module=module)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 130, proc.stderr
    assert "Traceback" not in proc.stderr and proc.stderr.strip() == f"{prog}: interrupted"


def test_compare_at_two_levels_stopped_in_the_second_keeps_the_first_and_the_finished() -> None:
    """Ctrl-C while `compare --level velocity torque` runs its second level: the first level's comparison
    and the second's finished episodes are printed (the interrupted one marked partial), exit 130."""
    proc = _start(ROBOT + ["compare", "--scene", "planar", "--level", "velocity", "torque", "--episodes", "3",
                           "--duration", "6", "--filters", "nominal", "--json"])
    _wait_for_line(proc, "] torque nominal seed 0")  # the second level's first episode finished
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().endswith("interrupted")
    doc = json.loads(out)
    assert doc["schema"].startswith("isf-robot-compare-levels/")
    velocity, torque = doc["levels"]["velocity"], doc["levels"]["torque"]
    assert velocity["partial"] is False and len(velocity["results"]["nominal"]["episodes"]) == 3
    assert torque["partial"] is True and 1 <= len(torque["results"]["nominal"]["episodes"]) < 3


def test_team_compare_stopped_keeps_the_finished_episodes() -> None:
    """Ctrl-C during `compare` on a scene with several arms (two workers): the finished episodes, marked partial."""
    proc = _start(ROBOT + ["compare", "--scene", "panda_pair", "--filters", "isf", "--episodes", "3",
                           "--coordination", "central", "--duration", "4", "--jobs", "2", "--d-bar", "0.12", "--json"])
    _wait_for_line(proc, "[1/3]")
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().endswith("interrupted")
    doc = json.loads(out)
    assert doc["partial"] is True and 1 <= doc["results"]["isf/central"]["episodes"] < 3
    assert _left_behind(proc.pid) == [], "worker or resource-tracker processes left behind"

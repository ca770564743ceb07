"""A long run's progress line: on a terminal only, throttled, erased at the end; the loop's calls; a real terminal."""

from __future__ import annotations

import io
import os
import subprocess
import sys

import pytest

from isf_robot.support.progress import AFTER_ENV, TerminalProgress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class _Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_nothing_before_after_then_at_most_every_interval_and_close_erases() -> None:
    out, clock = _Terminal(), _Clock()
    p = TerminalProgress(out, "panda_pole isf", after=1.0, every=0.5, clock=clock)
    p(0.0, 30.0)
    clock.now += 0.9
    p(3.0, 30.0)
    assert out.getvalue() == ""  # (a run shorter than a second prints nothing)
    clock.now += 0.2
    p(6.0, 30.0)
    assert out.getvalue() == "\r\x1b[Kpanda_pole isf  6.0 / 30.0 s simulated (20 %), 1 s"
    clock.now += 0.4
    p(7.5, 30.0)  # (0.4 s after the last line: not yet)
    clock.now += 0.1
    p(9.0, 30.0)
    assert out.getvalue().count("\r") == 2 and out.getvalue().endswith("9.0 / 30.0 s simulated (30 %), 2 s")
    p.close()
    assert out.getvalue().endswith("\r\x1b[K")  # (the summary starts on a clean line)
    p.close()
    assert out.getvalue().count("\r") == 3  # (erased once)


def test_close_without_a_line_writes_nothing_and_a_pipe_gets_no_reporter() -> None:
    out = _Terminal()
    TerminalProgress(out, clock=_Clock()).close()
    assert out.getvalue() == ""
    assert TerminalProgress.for_stream(io.StringIO()) is None  # (a pipe or a file: no progress in logs or JSON)
    assert isinstance(TerminalProgress.for_stream(_Terminal(), "x"), TerminalProgress)


def test_the_loop_reports_every_progress_steps_of_simulated_time() -> None:
    from isf_robot.arm import ArmSimulation, load_scene, resolve_params
    from isf_robot.arm.sim import PROGRESS_STEPS

    scene = load_scene("planar")
    sim = ArmSimulation(scene, "cbf", seed=0, params=resolve_params(scene, d_bar=0.05, calibrate=False))
    calls: list[tuple[float, float]] = []
    sim.progress = lambda t, total: calls.append((t, total))
    n = 2 * PROGRESS_STEPS + 10
    sim.run(n * sim.control_period)
    T = sim.control_period
    assert calls == [(k * PROGRESS_STEPS * T, n * T) for k in range(3)]


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_a_run_on_a_real_terminal_shows_its_progress_then_erases_it(outside_checkout, arm_compiled) -> None:  # type: ignore[no-untyped-def]
    import select
    import time

    master, slave = os.openpty()
    env = {**os.environ, AFTER_ENV: "0"}  # (the first line at once: the test does not depend on the machine's speed)
    p = subprocess.Popen([sys.executable, "-m", "isf_robot.cli", "run", "--scene", "panda_pole", "--filter", "cbf",
                          "--duration", "10"], stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL, env=env)
    os.close(slave)
    raw, deadline = b"", time.monotonic() + 300
    try:
        while time.monotonic() < deadline:
            if not select.select([master], [], [], 1.0)[0]:
                if p.poll() is not None:
                    break
                continue
            try:
                chunk = os.read(master, 4096)
            except OSError:  # (the terminal's other end closed: the command ended)
                break
            if not chunk:
                break
            raw += chunk
        out = p.communicate(timeout=max(1.0, deadline - time.monotonic()))[0].decode()
    finally:
        os.close(master)
        if p.poll() is None:
            p.kill()
    err = raw.decode()
    assert p.returncode == 0, err
    assert "panda_pole cbf  0.0 / 10.0 s simulated (0 %)" in err
    last = err.rindex("s simulated (")
    assert "\r\x1b[K" in err[last:]  # (the last line erased before the summary; warnings may follow it)
    assert out.startswith("scene panda_pole, filter cbf") and "simulated" not in out.splitlines()[1]


def test_a_run_restarts_the_clock_and_a_lost_terminal_ends_only_the_reporting() -> None:
    out, clock = _Terminal(), _Clock()
    p = TerminalProgress(out, after=1.0, every=0.5, clock=clock)
    clock.now += 5.0  # (built long before the run starts)
    p(0.0, 10.0)
    clock.now += 0.5
    p(1.0, 10.0)
    assert out.getvalue() == ""  # (the second since the run began, not since the reporter was made)

    class _Gone(_Terminal):
        def write(self, text: str) -> int:
            raise OSError("terminal gone")

    q = TerminalProgress(_Gone(), after=0.0, clock=clock)
    q(0.0, 10.0)  # (no exception: the run goes on)
    q.close()
    assert q.broken and not q.shown


def test_the_first_line_waits_for_the_environments_seconds(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv(AFTER_ENV, "0")
    assert TerminalProgress.for_stream(_Terminal()).after == 0.0  # type: ignore[union-attr]
    monkeypatch.setenv(AFTER_ENV, "soon")
    assert TerminalProgress.for_stream(_Terminal()).after == 1.0  # type: ignore[union-attr]
    monkeypatch.delenv(AFTER_ENV)
    assert TerminalProgress.for_stream(_Terminal()).after == 1.0  # type: ignore[union-attr]


def test_quiet_asks_for_no_reporter(monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from isf_robot.cli import main

    asked: list[str] = []
    monkeypatch.setattr(TerminalProgress, "for_stream", classmethod(lambda cls, stream, label="", **kw: asked.append(
        label)))
    assert main(["run", "--scene", "planar", "--filter", "nominal", "--duration", "0.1", "--quiet"]) == 0
    assert asked == []
    assert main(["run", "--scene", "planar", "--filter", "nominal", "--duration", "0.1"]) == 0
    assert asked == ["planar nominal"]  # (without --quiet: a reporter is asked for, for stderr)
    assert capsys.readouterr().out.startswith("scene planar")

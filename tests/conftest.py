"""Suite-wide: tests marked ``kernels`` compare the compiled kernels with the numpy path, so they skip under
``ISF_ROBOT_JIT=0`` (which turns the kernels off; the rest of the suite then tests the numpy path). Tests
marked ``time_limit(seconds)`` fail when they run longer: a wrong formula (a flipped normal, a wrong sign)
makes a simulation diverge into slow infeasible steps, and must fail in seconds, not after minutes."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator

import pytest

# The commands the tests start (``python -m isf_robot.cli``, ...) import the package the tests import (the installed
# one), not a checkout's copy from their working folder: one copy, so one disk cache of compiled kernels (in a clone
# with a non-editable install, two copies compiled every kernel twice: the suite took about 75 s longer).
os.environ.setdefault("PYTHONSAFEPATH", "1")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if os.environ.get("ISF_ROBOT_JIT", "1").strip().lower() in ("0", "false", "no", "off"):
        skip = pytest.mark.skip(reason="ISF_ROBOT_JIT=0 turns off the compiled kernels this test compares")
        for item in items:
            if "kernels" in item.keywords:
                item.add_marker(skip)


@pytest.fixture(autouse=True)
def _time_limit(request: pytest.FixtureRequest) -> Iterator[None]:
    mark = request.node.get_closest_marker("time_limit")
    if mark is None or not hasattr(signal, "SIGALRM"):
        yield
        return
    seconds = int(mark.args[0])

    def _over(signum: int, frame: object) -> None:
        raise TimeoutError(f"{request.node.nodeid} ran past its time limit of {seconds} s")

    old = signal.signal(signal.SIGALRM, _over)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture
def outside_checkout(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The test's working folder is an empty one, not the checkout: Ray adds the driver's working folder to its
    workers' import path, so from a clone's root they would import the clone's copy of the package and compile
    every kernel again for it (about 50 s per test in CI's clone, where the tests import the installed copy)."""
    monkeypatch.chdir(tmp_path)


@pytest.fixture(scope="session")
def local_ray(tmp_path_factory: pytest.TempPathFactory) -> Iterator[object]:
    """One local Ray instance (2 CPUs) for this test process's comparisons of the backends in-process.

    Starting and stopping Ray costs several seconds; :func:`~isf_robot.support.parallel.run_tasks` joins an
    instance that is running and leaves it running, so the tests that compare results share this one. Starting
    a private instance and stopping it (and Ctrl-C then) is what the commands do: the Ctrl-C tests of
    ``tests/arm/test_sweep_ray.py`` run them. Started from an empty folder (see :func:`outside_checkout`).
    """
    import ray

    here, address, term = os.getcwd(), os.environ.pop("RAY_ADDRESS", None), signal.getsignal(signal.SIGTERM)
    os.chdir(tmp_path_factory.mktemp("ray"))
    try:  # (a private instance, as run_tasks starts, even where RAY_ADDRESS names a cluster)
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="error")
    finally:
        os.chdir(here)
        if address is not None:
            os.environ["RAY_ADDRESS"] = address
        if term is not None:
            signal.signal(signal.SIGTERM, term)  # (ray.init replaces it)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="session")
def arm_compiled() -> None:
    """numba's cache of the arm's and the core's kernels, filled before a test that times a command starts its clock.

    A fresh clone has none: a command's first control steps compile them (about 30 s on one free core), and a
    Ctrl-C in that time is held until the compiler returns, so a test that signals "after the first episode" and
    expects the command to stop within seconds would time the compiler. Short runs of the strategies fill the
    cache (about 3 s when it is already there); the bound, 600 s, only catches a hang.
    """
    robot = [sys.executable, "-m", "isf_robot.cli"]
    for argv in (["compare", "--scene", "planar", "--episodes", "1", "--duration", "0.3", "--filters", "nominal", "cbf",
                  "isf", "--d-bar", "0.1", "--quiet"],
                 ["run", "--scene", "panda_pole", "--filter", "isf", "--duration", "0.5", "--d-bar", "0.04"]):
        done = subprocess.run(robot + argv, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr

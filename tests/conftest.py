"""Suite-wide: tests marked ``kernels`` compare the compiled kernels with the numpy path, so they skip under
``ISF_ROBOT_JIT=0`` (which turns the kernels off; the rest of the suite then tests the numpy path). Tests
marked ``time_limit(seconds)`` fail when they run longer: a wrong formula (a flipped normal, a wrong sign)
makes a simulation diverge into slow infeasible steps, and must fail in seconds, not after minutes."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator

import pytest


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


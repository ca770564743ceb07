"""run_tasks backends: the same (task, result) pairs here, in processes and on Ray; errors as themselves."""

from __future__ import annotations

import math

import pytest

from isf_robot.core.exceptions import ConfigError
from isf_robot.support.parallel import check_backend, run_tasks

TASKS = [0.0, 1.0, 2.0, 9.0, 16.0, 2.5]


def _pairs(backend: str, jobs: int) -> list[tuple[float, float]]:
    seen: list[tuple[int, int]] = []
    out = run_tasks(math.sqrt, TASKS, jobs=jobs, backend=backend,
                    on_result=lambda done, total, task, res: seen.append((done, total)))
    assert seen == [(i + 1, len(TASKS)) for i in range(len(TASKS))]  # one call per task, counted
    return sorted(out)


def test_processes_give_the_serial_pairs() -> None:
    serial = _pairs("processes", 1)
    assert serial == sorted((t, math.sqrt(t)) for t in TASKS)
    assert _pairs("processes", 2) == serial


def test_bad_backend_and_jobs_are_one_line_errors() -> None:
    with pytest.raises(ConfigError, match="valid backends: processes, ray"):
        check_backend("dask")
    with pytest.raises(ConfigError, match="--address goes with --backend ray"):
        check_backend("processes", "auto")
    with pytest.raises(ConfigError, match="jobs must be between 1 and"):
        run_tasks(math.sqrt, TASKS, jobs=0)


def test_a_task_error_stops_the_batch_as_itself() -> None:
    with pytest.raises(ValueError, match="math domain error"):
        run_tasks(math.sqrt, [1.0, -1.0, 4.0], jobs=2)


def test_ray_gives_the_same_pairs_and_errors(request: pytest.FixtureRequest) -> None:
    pytest.importorskip("ray")
    request.getfixturevalue("local_ray")  # (tests/conftest.py: one local instance, joined by run_tasks)
    assert _pairs("ray", 2) == _pairs("processes", 1)
    with pytest.raises(ValueError, match="math domain error"):
        run_tasks(math.sqrt, [1.0, -1.0, 4.0], jobs=2, backend="ray")


def test_a_ray_that_cannot_start_is_one_error(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import sys
    import types

    from isf_robot.support.parallel import RayStartError

    fake = types.ModuleType("ray")
    fake.is_initialized = lambda: False  # type: ignore[attr-defined]

    def init(**kw):  # type: ignore[no-untyped-def]
        raise RuntimeError("The current node timed out during startup.\nsecond line")

    fake.init = init  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "ray", fake)
    with pytest.raises(RayStartError, match="could not start a local Ray instance: RuntimeError: The current node"):
        run_tasks(math.sqrt, TASKS, jobs=2, backend="ray")
    with pytest.raises(RayStartError, match="could not join the Ray cluster at head:6379"):
        run_tasks(math.sqrt, TASKS, jobs=2, backend="ray", address="head:6379")

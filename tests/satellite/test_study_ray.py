"""isf-satellite study on Ray: the same orbits and statistics as local processes. Ray is in the
``test`` extra, so CI runs this; a checkout without it skips it, except under ``CI`` where a missing
Ray fails instead of passing quietly (as the arm sweep's Ray tests)."""

from __future__ import annotations

import os

import pytest

from satellite.study.paired import StudySettings, plan, run_study

try:
    import ray  # noqa: F401

    HAVE_RAY = True
except ImportError:
    HAVE_RAY = False


def _numbers(doc: dict) -> dict:
    """The study without wall times (machine-dependent) and the backend's own settings."""
    runs = sorted(({k: v for k, v in r.items() if k != "wall_s"} for r in doc["runs"]),
                  key=lambda r: (r["config"], r["seed"], r["inclination_deg"]))
    return {"runs": runs, "comparisons": doc["comparisons"], "partial": doc["partial"],
            "orbits_done": doc["orbits_done"]}


@pytest.mark.usefixtures("outside_checkout")  # Ray's workers import the installed package (tests/conftest.py)
@pytest.mark.skipif(not HAVE_RAY and not os.environ.get("CI"),
                    reason="ray not installed (pip install '.[ray]'); CI installs it with the test extra")
@pytest.mark.usefixtures("local_ray")  # (tests/conftest.py: one local instance, joined by run_tasks)
def test_study_on_local_ray_equals_local_processes() -> None:
    configs = plan(["greedy", "periodic"], ["kepler"], [0.5])
    starts = [(0, 45.0), (1, 15.0), (2, 75.0)]
    settings = StudySettings(hours=1.5, gravity="sh8")
    seen: list[tuple[int, int]] = []
    on_ray = run_study(configs, starts, settings, jobs=2, backend="ray",
                       progress=lambda done, total, task, run: seen.append((done, total)))
    local = run_study(configs, starts, settings, jobs=2)
    assert sorted(seen) == [(i, 6) for i in range(1, 7)]
    assert _numbers(on_ray) == _numbers(local)
    assert not on_ray["partial"] and on_ray["orbits_done"] == 6
    assert len({(r["config"], r["seed"], r["triggers"], r["min_h"]) for r in on_ray["runs"]}) == 6
    assert len({r["min_h"] for r in on_ray["runs"]}) > 1  # not one answer copied everywhere
    assert all(r["completed"] and r["min_h"] > 0 for r in on_ray["runs"])

"""Fixtures of the Rerun-layer tests: one recorded arm run and one recorded satellite run."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from isf_robot.core import Observer


@dataclass
class Collector(Observer):
    """Keeps everything the loop sends, to compare with what is read back."""

    info: dict[str, Any] = field(default_factory=dict)
    steps: list[Any] = field(default_factory=list)
    events: list[Any] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)

    def on_start(self, info: Any) -> None:
        self.info = dict(info)

    def on_step(self, record: Any) -> None:
        self.steps.append(record)

    def on_event(self, event: Any) -> None:
        self.events.append(event)

    def on_finish(self, summary: Any) -> None:
        self.summary = dict(summary)


@dataclass
class RecordedRun:
    path: Path
    result: Any
    collector: Collector
    recorder: Any


@pytest.fixture(scope="session")
def arm_run(tmp_path_factory: pytest.TempPathFactory) -> RecordedRun:
    """The intermittent filter on planar_moving for 6 s (several on/off switches), recorded."""
    from isf_robot.arm import load_scene, resolve_params
    from isf_robot.arm.sim import ArmSimulation
    from isf_robot.record import ArmRecorder, arm_blueprint, open_stream

    scene = load_scene("planar_moving")
    path = tmp_path_factory.mktemp("arm") / "isf.rrd"
    rec = ArmRecorder(open_stream("isf_robot_arm", rrd_path=path, blueprint=arm_blueprint()),
                      capacity=500)  # several flushes per run
    col = Collector()
    # (no hand-over, no predictive off trigger: the designed ones switch once in 6 s; these tests read switches back)
    params = resolve_params(scene, blend=0.0, horizon=0.0)
    res = ArmSimulation(scene, "isf", seed=0, params=params, observers=[col, rec]).run(6.0)
    return RecordedRun(path, res, col, rec)


@pytest.fixture(scope="session")
def sat_run(tmp_path_factory: pytest.TempPathFactory) -> RecordedRun:
    """A 60 h greedy satellite run, recorded."""
    from isf_robot.record import SatelliteRecorder, open_stream, satellite_blueprint
    from satellite.orbit.simulate import simulate

    path = tmp_path_factory.mktemp("sat") / "greedy.rrd"
    rec = SatelliteRecorder(open_stream("isf_robot_satellite", rrd_path=path, blueprint=satellite_blueprint()),
                            capacity=64)
    col = Collector()
    res = simulate("greedy", 60.0, observers=[col, rec], miet_samples=200)
    return RecordedRun(path, res, col, rec)

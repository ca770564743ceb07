"""An interrupted comparison or sweep prints a table that says how many episodes finished."""

from __future__ import annotations

import re

import pytest

from isf_robot.arm.compare import Comparison, SceneSpec, format_table, summarize
from isf_robot.arm.sweep import SweepPoint, format_sweep, run_sweep
from isf_robot.support.parallel import Interrupted


def _run(seed: int) -> dict:
    return {"seed": seed, "duty_cycle": 0.5, "on_switches": 2, "goals_reached": 1}


def test_partial_comparison_says_how_many_episodes_finished_per_strategy() -> None:
    results = {"nominal": summarize([_run(s) for s in range(4)]), "cbf": summarize([_run(s) for s in range(4)]),
               "isf": summarize([_run(s) for s in range(3)])}
    part = Comparison(scene="planar", episodes=10, seeds=tuple(range(10)), results=results, partial=True)
    text = format_table(part)
    title = text.splitlines()[0]
    assert title.startswith("PARTIAL")
    for want in ("nominal: 4 of 10 episodes finished", "cbf: 4 of 10 episodes finished",
                 "isf: 3 of 10 episodes finished"):
        assert want in title, title
    assert "10 episode(s) per strategy" not in text  # the asked-for count alone would read as done
    assert part.as_dict()["finished"] == {"nominal": 4, "cbf": 4, "isf": 3}
    full = Comparison(scene="planar", episodes=4, seeds=tuple(range(4)), results={"cbf": results["cbf"]})
    assert "4 episode(s) per strategy" in format_table(full) and "finished" not in format_table(full)
    assert full.as_dict()["finished"] == {"cbf": 4}


def test_interrupted_sweep_table_counts_the_finished_episodes() -> None:
    seen = []

    def stop_after_three(done, total, task, r):  # type: ignore[no-untyped-def]
        seen.append(done)
        if done == 3:
            raise KeyboardInterrupt

    pts = [SweepPoint("cbf", {}), SweepPoint("isf", {"c": 0.1})]
    with pytest.raises(Interrupted) as err:
        run_sweep([SceneSpec(name="planar")], pts, [0, 1], duration=0.1, d_bar=0.05, progress=stop_after_three)
    sweep = err.value.partial
    assert sweep is not None and sweep["partial"] is True
    text = format_sweep(sweep)
    assert "3 of 4 episodes finished" in text.splitlines()[0], text
    cells = [re.search(r"\s(\d+/\d+)\s", line).group(1) for line in text.splitlines()[3:]]  # type: ignore[union-attr]
    assert sorted(cells) == ["1/2", "2/2"], text
    full = run_sweep([SceneSpec(name="planar")], pts[:1], [0], duration=0.1, d_bar=0.05)
    assert "finished" not in format_sweep(full) and "1 seed(s) per point" in format_sweep(full)

"""TeamBars: one row per episode, one column per arm; anything else is refused with the shape it had."""

from __future__ import annotations

import numpy as np
import pytest

from isf_robot.core import ConfigError
from isf_robot.plots.team import TeamBars


def _bars(**kw: object) -> TeamBars:
    base: dict[str, object] = {"group": "isf/central", "arms": ("a", "b"), "duty_cycle": [[0.1, 0.2], [0.3, 0.4]],
                               "on_switches": [[1, 2], [3, 4]], "intervention": [[1.0, 2.0], [3.0, 4.0]],
                               "min_off_s": [[0.5, np.nan], [0.6, 0.7]]}
    return TeamBars(**{**base, **kw})  # type: ignore[arg-type]


def test_team_bars_take_episodes_by_arms() -> None:
    b = _bars()
    assert b.duty_cycle.shape == (2, 2) and b.arms == ("a", "b")
    one = _bars(duty_cycle=[0.1, 0.2], on_switches=[1, 2], intervention=[1.0, 2.0], min_off_s=[0.5, 0.6])
    assert one.duty_cycle.shape == (1, 2)  # one episode as a flat row


@pytest.mark.parametrize("bad", [[0.1, 0.2, 0.3, 0.4], [[0.1], [0.2]], [[0.1, 0.2, 0.3]]])
def test_team_bars_refuse_other_shapes(bad: object) -> None:
    with pytest.raises(ConfigError, match=r"duty_cycle must have shape \(episodes, 2\)"):
        _bars(duty_cycle=bad)

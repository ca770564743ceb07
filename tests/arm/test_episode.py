"""Episode setup: seeded initial configurations, goals and obstacle phases; bad seeds."""

from __future__ import annotations

import pytest

from isf_robot.arm import episode_setup
from isf_robot.core import ConfigError


@pytest.mark.parametrize("seed", [-1, 2.5, True])
def test_episode_setup_rejects_bad_seed(planar, seed) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        episode_setup(planar, seed)


def test_same_seed_same_setup_other_seed_other_setup(planar) -> None:  # type: ignore[no-untyped-def]
    a, b, c = episode_setup(planar, 3), episode_setup(planar, 3), episode_setup(planar, 4)
    assert (a.q0 == b.q0).all() and (a.goals == b.goals).all() and a.time_offset == b.time_offset
    assert not (a.q0 == c.q0).all()

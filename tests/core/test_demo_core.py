"""The core demo rejects bad input with one-line errors (library and command line)."""

import pytest

from isf_robot.cli import main
from isf_robot.core import ConfigError
from isf_robot.demo_core import run_episode


@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_core_demo_rejects_bad_seed(seed):
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        run_episode("isf", seed, duration=1.0)


@pytest.mark.parametrize("duration", [float("nan"), float("inf"), -1.0])
def test_core_demo_rejects_bad_duration(duration):
    with pytest.raises(ConfigError, match="duration"):
        run_episode("isf", 0, duration=duration)


@pytest.mark.parametrize(("argv", "needle"), [
    (["core-demo", "--duration", "nan"], "--duration"),
    (["core-demo", "--duration", "inf"], "--duration"),
    (["core-demo", "--seed", "-1"], "--seed"),
])
def test_core_demo_cli_bad_input_one_line(argv, needle, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err and "Traceback" not in err

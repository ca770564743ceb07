import json
import subprocess
import sys

from isf_robot.cli import main


def test_core_demo_table(capsys):
    assert main(["core-demo", "--episodes", "2", "--duration", "8"]) == 0
    out = capsys.readouterr().out
    for word in ("nominal", "cbf", "isf", "duty cycle"):
        assert word in out


def test_core_demo_json_and_bad_input(capsys):
    assert main(["core-demo", "--episodes", "1", "--duration", "5", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert set(data["results"]) == {"nominal", "cbf", "isf"}
    assert data["results"]["cbf"][0]["min_barrier"] >= -1e-9
    assert main(["core-demo", "--episodes", "0"]) == 2
    assert "--episodes must be >= 1" in capsys.readouterr().err


def test_console_script_help_runs():
    out = subprocess.run([sys.executable, "-m", "isf_robot.cli", "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "core-demo" in out.stdout

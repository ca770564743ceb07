"""REPRODUCTION.md's figures: the check subset reruns to the committed numbers, and the comparison can fail."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "satellite_reproduction.py"
CHECK = ROOT / "docs" / "figures" / "satellite_repro_check.json"


@pytest.fixture(scope="module")
def repro():  # type: ignore[no-untyped-def]
    sys.path.insert(0, str(SCRIPT.parent))
    try:
        import satellite_reproduction

        yield satellite_reproduction
    finally:
        sys.path.remove(str(SCRIPT.parent))


def test_the_check_subset_reruns_to_the_committed_figures() -> None:
    """``--check``: 9 orbits of 24 h; counts exactly, floats to 1e-4 (exit 0 only when all agree)."""
    out = subprocess.run([sys.executable, str(SCRIPT), "--check"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "9 runs, 0 difference(s)" in out.stdout


def test_the_comparison_reports_a_changed_count_and_a_drifted_float(repro) -> None:  # type: ignore[no-untyped-def]
    want = json.loads(CHECK.read_text())["studies"]["check"]
    assert repro.compare(want, want) == []
    got = copy.deepcopy(want)
    got["runs"][0]["triggers"] += 1
    got["runs"][1]["total_dv"] *= 1.0 + 3 * repro.CHECK_RTOL
    got["runs"][2]["total_dv"] *= 1.0 + 0.3 * repro.CHECK_RTOL  # inside the tolerance
    diffs = repro.compare(got, want)
    assert len(diffs) == 2 and "triggers" in diffs[0] and "total_dv" in diffs[1]
    del got["runs"][3]
    assert any("missing" in d for d in repro.compare(got, want))

"""The suite's ``time_limit`` marker (tests/conftest.py) fails a test that runs past it, in a real pytest run."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path


def test_a_test_past_its_time_limit_fails_and_one_within_it_passes(tmp_path: Path) -> None:
    shutil.copy(Path(__file__).with_name("conftest.py"), tmp_path / "conftest.py")
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    time_limit(seconds): limit\n    kernels: k\n")
    (tmp_path / "test_limits.py").write_text(
        "import time, pytest\n"
        "@pytest.mark.time_limit(1)\ndef test_slow():\n    time.sleep(20)\n"
        "@pytest.mark.time_limit(10)\ndef test_quick():\n    time.sleep(0.1)\n")
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
                          str(tmp_path)], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert "1 failed, 1 passed" in out.stdout, out.stdout + out.stderr
    assert "ran past its time limit of 1 s" in out.stdout

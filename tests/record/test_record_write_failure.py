"""A recording whose file cannot be written (the disk fills up): the run's results are still
printed, the command says so in one line and exits 2, the data written so far stays under
``<name>.partial`` and an existing recording under the target name is left as it was.

Rerun's file writer runs on its own thread and reports a failed write only when the stream is
flushed (``RuntimeError: File-writer thread shut down prematurely``, as seen on a full tmpfs);
the tests make that flush fail the same way.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import rerun as rr

from isf_robot.cli import main
from isf_robot.record.errors import take_deferred_errors


@pytest.fixture
def full_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    def flush(self: rr.RecordingStream, *args: object, **kwargs: object) -> None:
        raise RuntimeError("File-writer thread shut down prematurely")

    monkeypatch.setattr(rr.RecordingStream, "flush", flush)
    take_deferred_errors()


def test_run_prints_its_results_then_reports_the_failed_recording(
        tmp_path: Path, full_disk: None, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "good.rrd"
    target.write_bytes(b"an earlier recording")
    code = main(["run", "--scene", "planar_moving", "--duration", "0.2", "--json", "--rrd", str(target)])
    out, err = capsys.readouterr()
    assert code == 2
    assert json.loads(out)["scene"] == "planar_moving"  # the results were not lost
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("isf-robot run: error: the recording could not be written")
    assert "good.rrd.partial" in lines[0]
    assert target.read_bytes() == b"an earlier recording"
    assert (tmp_path / "good.rrd.partial").exists()
    assert take_deferred_errors() == []  # reported once


def test_compare_stops_with_the_failed_recording(
        tmp_path: Path, full_disk: None, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["compare", "--scene", "planar_moving", "--episodes", "1", "--duration", "0.2",
                 "--filters", "cbf", "--rrd", str(tmp_path / "out")])
    _, err = capsys.readouterr()
    assert code == 2
    assert "error: the recording could not be written" in err.strip().splitlines()[-1]
    assert not list((tmp_path / "out").glob("*.rrd"))  # nothing renamed into place


def test_a_reported_failure_is_not_reported_again_by_the_next_command(
        tmp_path: Path, full_disk: None, capsys: pytest.CaptureFixture[str]) -> None:
    main(["compare", "--scene", "planar_moving", "--episodes", "1", "--duration", "0.2",
          "--filters", "cbf", "--rrd", str(tmp_path / "out")])
    capsys.readouterr()
    assert take_deferred_errors() == []
    assert main(["scenes"]) == 0
    assert "error" not in capsys.readouterr().err

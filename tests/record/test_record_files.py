"""Blueprints build; missing, truncated, corrupt, foreign and unfinished files give clear errors."""

from __future__ import annotations

import os

import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import RrdReader

from isf_robot.cli import main
from isf_robot.record import (
    ColumnBuffer,
    RecordError,
    RecordingReadError,
    RerunRecorder,
    ViewerUnavailableError,
    blueprint_for,
    find_viewer,
    open_stream,
    read_many,
    read_rrd,
)


@pytest.mark.parametrize("kind", ["arm", "satellite", "generic"])
def test_blueprints_build_and_ship(kind: str, tmp_path) -> None:  # type: ignore[no-untyped-def]
    bp = blueprint_for(kind)
    assert isinstance(bp, rrb.Blueprint)
    path = tmp_path / f"{kind}.rrd"
    rec = open_stream("isf_robot", rrd_path=path, blueprint=bp)
    r = RerunRecorder(rec)
    r.on_start({})
    r.on_finish({})
    reader = RrdReader(path)
    assert len(reader.blueprints()) == 1 and len(reader.recordings()) == 1


def test_unknown_blueprint_kind() -> None:
    with pytest.raises(RecordError, match="valid kinds"):
        blueprint_for("boat")


def test_missing_and_directory(tmp_path) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(RecordingReadError, match="no such file") as e:
        read_rrd(tmp_path / "nope.rrd")
    assert "nope.rrd" in str(e.value)
    with pytest.raises(RecordingReadError, match="directory"):
        read_rrd(tmp_path)
    with pytest.raises(RecordingReadError, match="no .rrd file"):
        read_many([tmp_path])


def test_empty_and_foreign_files(tmp_path) -> None:  # type: ignore[no-untyped-def]
    empty = tmp_path / "empty.rrd"
    empty.write_bytes(b"")
    with pytest.raises(RecordingReadError, match="empty") as e:
        read_rrd(empty)
    assert "empty.rrd" in str(e.value)
    text = tmp_path / "notes.rrd"
    text.write_text("these are not the recordings you are looking for\n")
    with pytest.raises(RecordingReadError, match="not a Rerun"):
        read_rrd(text)


def test_truncated_and_corrupt(arm_run, tmp_path) -> None:  # type: ignore[no-untyped-def]
    data = arm_run.path.read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(RecordingReadError) as e:
        read_rrd(cut)
    assert "cut.rrd" in str(e.value)
    assert "truncated" in str(e.value) or "incomplete" in str(e.value)
    bad = tmp_path / "bad.rrd"
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 256, 4000, dtype=np.uint8).tobytes()
    bad.write_bytes(data[:300] + noise + data[4300:])
    with pytest.raises(RecordingReadError) as e:
        read_rrd(bad)
    assert "bad.rrd" in str(e.value)


def test_foreign_rerun_recording(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "other.rrd"
    rec = rr.RecordingStream("someone_else")
    rec.save(path)
    rec.log("points", rr.Points3D([[0, 0, 0]]))
    rec.flush()
    rec.disconnect()
    with pytest.raises(RecordingReadError, match="not an isf_robot run log"):
        read_rrd(path)
    partial = path.rename(tmp_path / "run.rrd.partial")  # (an interrupted run's file, with nothing of the run in it)
    with pytest.raises(RecordingReadError, match="an unfinished recording"):
        read_rrd(partial)


def test_unfinished_run_is_reported(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "crash.rrd"
    rec = open_stream("isf_robot", rrd_path=path)
    r = RerunRecorder(rec)
    r.on_start({"strategy": "isf"})
    from types import SimpleNamespace

    for k in range(10):
        r.on_step(SimpleNamespace(t=0.01 * k, dt=0.01, on=False, intervention_rate=0.0, qp_solved=False,
                                  min_barrier=1.0))
    r.close()  # no on_finish: the run "crashed"
    with pytest.raises(RecordingReadError, match="incomplete"):
        read_rrd(path)


def test_collector_is_held_only_while_recording(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import gc

    assert gc.get_freeze_count() == 0
    first, second = (RerunRecorder(open_stream("isf_robot", rrd_path=tmp_path / f"{i}.rrd")) for i in range(2))
    first.on_start({"strategy": "isf"})
    assert gc.get_freeze_count() > 0  # (what lived before the run: kept off the collector's full passes)
    second.on_start({"strategy": "isf"})
    first.on_finish({})
    assert gc.get_freeze_count() > 0  # (the other recorder still runs)
    second.close(complete=False)  # (an aborted run also hands them back)
    assert gc.get_freeze_count() == 0
    second.close()
    assert gc.get_freeze_count() == 0
    third = RerunRecorder(open_stream("isf_robot", rrd_path=tmp_path / "3.rrd"))
    third.on_start({"strategy": "isf"})
    assert gc.get_freeze_count() > 0
    del third  # (dropped without close: released all the same)
    gc.collect()
    assert gc.get_freeze_count() == 0


def test_cli_errors_name_the_file(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["replay", str(tmp_path / "gone.rrd")]) == 2
    err = capsys.readouterr().err
    assert "gone.rrd" in err and "no such file" in err and "Traceback" not in err


def test_find_viewer_without_display(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("PATH", os.defpath)
    import sys

    if sys.platform.startswith("linux"):
        with pytest.raises(ViewerUnavailableError):
            find_viewer()


def test_stream_needs_a_destination() -> None:
    with pytest.raises(RecordError, match="destination"):
        open_stream("isf_robot")


def test_buffer_memory_is_bounded(tmp_path) -> None:  # type: ignore[no-untyped-def]
    rec = open_stream("isf_robot", rrd_path=tmp_path / "b.rrd")
    buf = ColumnBuffer(rec, capacity=100)
    ch = buf.scalars("/x", 3)
    derived_rows = []
    ch2 = buf.channel("/y", {"v": ((), np.float64)}, None,
                      derived=(("/y/pos", lambda t, a: derived_rows.append(len(t)) or None),))
    for k in range(1050):
        ch.push(0.1 * k, (k, k + 1, k + 2))
        ch2.push(0.1 * k, float(k))
        assert buf.buffered_rows <= 2 * 100
    assert ch.rows_sent == 1000 and len(ch) == 50
    buf.flush()
    assert ch.rows_sent == 1050 and derived_rows == [100] * 10 + [50]
    rec.flush()
    rec.disconnect()
    with pytest.raises(RecordError):
        ColumnBuffer(rec, capacity=0)


def test_any_values_are_rerun_own() -> None:
    """``any_values`` makes the components ``rr.AnyValues`` makes of the same values (its types, its values), so
    what the recorder logs with it reads back as before; other values are left to Rerun."""
    import numpy as np
    import rerun as rr

    from isf_robot.record.recorder import any_values

    fields = {"flag": True, "count": 5, "big": 2**40, "ratio": 0.25, "text": "a,b", "empty": "",
              "ids": np.array([3, 1, 4], dtype=np.int64), "xs": np.array([0.5, 1.5]), "mixed": [1, 2]}
    ours, theirs = list(any_values(**fields).as_component_batches()), list(rr.AnyValues(**fields).as_component_batches())
    assert [c.component_descriptor() for c in ours] == [c.component_descriptor() for c in theirs]
    for a, b in zip(ours, theirs):
        assert a.as_arrow_array().type == b.as_arrow_array().type, a.component_descriptor()
        assert a.as_arrow_array().equals(b.as_arrow_array()), a.component_descriptor()

"""`compare --rrd DIR`: the strategies of each seed side by side in one recording, read back."""

from __future__ import annotations

import numpy as np
from rerun.chunk import RrdReader

from isf_robot.cli import main
from isf_robot.record import read_columns, read_rrd
from isf_robot.record.side_by_side import SUBDIR, write_side_by_side


def _origins(path) -> list[str]:  # type: ignore[no-untyped-def]
    reader = RrdReader(path)
    out: list[str] = []
    for entry in reader.blueprints():
        for chunk in reader.stream(store=entry):
            b = chunk.to_record_batch()
            for name in b.schema.names:
                if name.endswith(":space_origin"):
                    out.extend(str(v[0] if isinstance(v, list) else v) for v in b.column(name).to_pylist())
    return out


def test_compare_writes_one_side_by_side_recording_per_seed(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "cmp"
    assert main(["compare", "--scene", "planar_moving", "--episodes", "2", "--duration", "1",
                 "--filters", "isf", "cbf", "--quiet", "--rrd", str(out)]) == 0
    err = capsys.readouterr().err
    files = sorted(p.name for p in (out / SUBDIR).glob("*.rrd"))
    assert files == ["planar_moving-seed0.rrd", "planar_moving-seed1.rrd"]
    assert "side by side" in err
    both = out / SUBDIR / "planar_moving-seed1.rrd"
    for strategy in ("isf", "cbf"):
        src = out / f"planar_moving-{strategy}-seed1.rrd"
        (log,) = read_rrd(src)
        assert (log.info["scene"], log.info["strategy"], log.info["seed"]) == ("planar_moving", strategy, 1)
        for entity in ("/plots/barrier/min", "/plots/mode", "/plots/command/correction_norm"):
            a = read_columns(src, entity)
            b = read_columns(both, f"/compare/{strategy}{entity}")
            np.testing.assert_array_equal(b["Scalars:scalars"], a["Scalars:scalars"])
            np.testing.assert_array_equal(b["sim_time"], a["sim_time"])
    origins = _origins(both)
    # one column of three views per strategy, columns in the order asked for
    assert sorted(o for o in origins if o.startswith("/compare/isf/")) == [
        "/compare/isf/plots/barrier", "/compare/isf/plots/command", "/compare/isf/plots/mode"]
    assert len([o for o in origins if o.startswith("/compare/cbf/")]) == 3
    info = [c.to_record_batch() for c in RrdReader(both).stream() if c.entity_path == "/run/info"]
    assert info[0].column("strategies").to_pylist()[0] in ("isf,cbf", ["isf,cbf"])
    # replay of the directory still reads the per-run files only
    assert main(["replay", str(out), "--json"]) == 0


def test_same_strategy_twice_is_an_error(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import shutil

    import pytest

    from isf_robot.record.errors import RecordingReadError

    out = tmp_path / "cmp"
    assert main(["compare", "--scene", "planar_moving", "--episodes", "1", "--duration", "0.3",
                 "--filters", "isf", "--quiet", "--rrd", str(out)]) == 0
    shutil.copy(out / "planar_moving-isf-seed0.rrd", out / "copy.rrd")
    with pytest.raises(RecordingReadError, match="same strategy"):
        write_side_by_side(out)

"""What the viewer shows of a satellite run: the band on r(t), impulses as markers, the whole run."""

from __future__ import annotations

import numpy as np
from rerun.chunk import RrdReader

from isf_robot.record import read_columns, read_rrd


def test_band_lines_on_the_radius_plot(sat_run) -> None:  # type: ignore[no-untyped-def]
    (log,) = read_rrd(sat_run.path)
    inner, outer = log.info["band_over_R"]
    samples = sat_run.collector.steps
    for name, value in (("band_inner", inner), ("band_outer", outer)):
        col = read_columns(sat_run.path, f"/plots/radius/{name}")
        assert np.all(col["Scalars:scalars"] == value)
        assert col["sim_time"].min() == 0.0
        assert abs(col["sim_time"].max() - samples[-1].t) < 1e-6  # the line spans the run


def test_every_impulse_is_a_marker(sat_run) -> None:  # type: ignore[no-untyped-def]
    res = sat_run.result
    assert res.triggers > 3 and set(res.kinds) == {"greedy"}
    col = read_columns(sat_run.path, "/plots/impulses/dv")
    np.testing.assert_allclose(col["sim_time"], [e.t for e in res.events], atol=1e-6)
    np.testing.assert_allclose(col["Scalars:scalars"], [np.linalg.norm(e.v) for e in res.events], rtol=1e-12)
    static = [c.to_record_batch() for c in RrdReader(sat_run.path).stream()
              if c.entity_path == "/plots/impulses/dv" and c.is_static]
    assert any("SeriesPoints:markers" in b.schema.names for b in static)


def test_plots_span_the_whole_run(sat_run) -> None:  # type: ignore[no-untyped-def]
    (log,) = read_rrd(sat_run.path)
    reader = RrdReader(sat_run.path)
    ends = []
    for entry in reader.blueprints():
        for chunk in reader.stream(store=entry):
            b = chunk.to_record_batch()
            for name in b.schema.names:
                if name.endswith("TimeAxis:view_range"):
                    ends.extend(b.column(name).to_pylist())
    assert ends, "no time axis range in the blueprint"
    want_ns = int(round(3600e9 * float(log.info["hours"])))
    flat = str(ends)
    assert str(want_ns) in flat, flat[:300]

"""Static figures (`isf-robot plot`) from short recorded runs: what is drawn is what the run did."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="the 'plots' extra (matplotlib) is not installed")

from isf_robot.cli import main  # noqa: E402
from isf_robot.plots import (  # noqa: E402
    OrbitSeries,
    RunSeries,
    break_gaps,
    on_intervals,
    run_figure,
    satellite_figure,
    save_figure,
)
from isf_robot.record.figure_data import arm_series, satellite_series  # noqa: E402
from isf_robot.record.replay import read_rrd, replay_metrics  # noqa: E402


def test_on_intervals_and_gaps_known_answers() -> None:
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    on = np.array([True, False, True, True, False, True])
    assert np.allclose(on_intervals(t, on, 0.1), [(0.0, 0.1), (0.2, 0.4), (0.5, 0.6)])
    assert on_intervals(t, np.zeros(6, bool), 0.1) == []
    tt, yy = break_gaps(np.array([0.0, 1.0, 5.0, 6.0]), np.array([1.0, 2.0, 3.0, 4.0]), 1.5)
    assert np.array_equal(np.isnan(tt), [False, False, True, False, False]) and np.isnan(yy[2])
    assert list(yy[[0, 1, 3, 4]]) == [1, 2, 3, 4]


def test_run_figure_shades_exactly_the_on_intervals(arm_run) -> None:  # type: ignore[no-untyped-def]
    run = RunSeries(**arm_series(read_rrd(arm_run.path)[0]))
    fig = run_figure(run)
    ax_h, ax_xi, _ = fig.axes
    # the shaded spans start at the run's 'on' events and end at its 'off' events (or at the end)
    spans = sorted((p.get_x(), p.get_x() + p.get_width()) for p in ax_h.patches)
    events = arm_run.collector.events
    ons = [e.t for e in events if e.kind == "on"]
    offs = [e.t for e in events if e.kind == "off"]
    recs = arm_run.collector.steps
    if len(offs) < len(ons):
        offs.append(recs[-1].t + recs[-1].dt)
    assert len(ons) >= 3
    assert np.allclose(spans, list(zip(ons, offs)), atol=1e-9, rtol=0)
    # the h line is the true-geometry minimum of every step, as the recorder computes it live
    want = [arm_run.recorder.replay_row(r)[5] for r in recs]
    assert np.allclose(ax_h.lines[0].get_ydata(), want, equal_nan=True)
    # Xi_on with its two thresholds: 0 (on) and c (off), c from the run
    c = float(arm_run.collector.info["c"])
    levels = sorted(float(ln.get_ydata()[0]) for ln in ax_xi.lines[1:])
    assert levels == pytest.approx([0.0, c])


def test_plot_cli_writes_a_reproducible_png(arm_run, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    from PIL import Image

    out = tmp_path / "run.png"
    assert main(["plot", str(arm_run.path), "-o", str(out)]) == 0
    first = out.read_bytes()
    assert Image.open(out).size == (800, 670)
    assert main(["plot", str(arm_run.path), "-o", str(out)]) == 0
    assert out.read_bytes() == first  # no date or version stamp: the same run gives the same file


def test_compare_bars_are_the_replayed_metrics(arm_run, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    d = tmp_path / "cmp"
    assert main(["compare", "--scene", "planar_moving", "--episodes", "1", "--filters", "isf", "nominal",
                 "--duration", "4", "--quiet", "--rrd", str(d)]) == 0
    from isf_robot.cli.plot import _recordings

    class Args:
        inputs = [d]
        hours = 150.0
        title = None

    fig, what = _recordings(Args())  # type: ignore[arg-type]
    assert "2 strategies" in what
    bars_ax = [ax for ax in fig.axes if ax.get_title() == "duty cycle"][0]
    heights = [p.get_height() for p in bars_ax.patches]
    logs = {log.info["strategy"]: log for log in read_rrd(d / "planar_moving-nominal-seed0.rrd")
            + read_rrd(d / "planar_moving-isf-seed0.rrd")}
    # registry order (nominal before isf), each bar the replayed duty cycle
    assert heights == pytest.approx([replay_metrics(logs[s])["duty_cycle"] for s in ("nominal", "isf")])
    assert heights[0] == 0.0 and heights[1] > 0.0
    out = tmp_path / "cmp.svg"
    assert main(["plot", str(d), "-o", str(out)]) == 0 and out.read_text().lstrip().startswith("<?xml")


def test_satellite_figure_stars_every_impulse_in_the_window(sat_run, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    orbit = OrbitSeries(**satellite_series(read_rrd(sat_run.path)[0]))
    impulses = [e for e in sat_run.collector.events if hasattr(e, "kind")]
    assert len(impulses) >= 3
    for hours in (150.0, 20.0):
        ax_r, ax_x = satellite_figure(orbit, hours).axes
        stars = np.concatenate([ln.get_xdata() for ln in ax_x.lines if ln.get_marker() == "*"])
        want = [e.t / 3600.0 for e in impulses if e.t / 3600.0 <= hours]
        assert np.allclose(np.sort(stars), want)
        edges = sorted(float(ln.get_ydata()[0]) for ln in ax_r.lines if ln.get_linestyle() == "--")
        assert edges == pytest.approx([1.6, 2.4])
    assert main(["plot", str(sat_run.path), "-o", str(tmp_path / "sat.png"), "--hours", "30"]) == 0


def test_tau_figure_draws_the_fit(tmp_path: Path) -> None:
    from satellite.control.tau import DEFAULT_RADII, TauData, fit_tau, tau_document

    r = np.asarray(DEFAULT_RADII, dtype=float)
    rng = np.random.default_rng(0)
    times = (2.0 + 3.0 * (1.0 - ((r - 2.0) / 0.4) ** 2))[:, None] + rng.uniform(-0.3, 0.3, (r.size, 5))
    R = 160.0
    data = TauData(r, times, 50.0, 0, True, 0.0, 1)
    fit = fit_tau(data, (0.4 * R) ** 2, R, 2)
    path = tmp_path / "tau.json"
    path.write_text(json.dumps(tau_document(data, fit, {})))
    out = tmp_path / "tau.pdf"
    assert main(["plot", str(path), "-o", str(out)]) == 0 and out.read_bytes().startswith(b"%PDF")
    from isf_robot.cli.plot import _tau

    fig, _ = _tau(path)
    curve = [ln for ln in fig.axes[0].lines if ln.get_label() == "fitted tau_p"][0]
    x, y = curve.get_xdata(), curve.get_ydata()
    i = int(np.argmin(abs(x - 2.0)))
    assert x[i] == pytest.approx(2.0) and y[i] == pytest.approx(fit.tau_p(fit.h_max) / 3600.0)
    assert y[0] == pytest.approx(fit.tau_p(0.0) / 3600.0)  # the band's edge: h = 0


def test_errors_are_one_line(arm_run, tmp_path: Path, capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    assert main(["plot", str(arm_run.path), "-o", str(tmp_path / "x.jpg")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and ".png, .svg, .pdf" in err
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if the extra were missing
    assert main(["plot", str(arm_run.path), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "isf-robot[plots]" in err
    assert not (tmp_path / "x.png").exists()


def test_series_are_checked() -> None:
    from isf_robot.core import ConfigError

    with pytest.raises(ConfigError, match=r"h must have shape \(3,\)"):
        RunSeries("x", "isf", [0, 1, 2], [1, 1, 1], [0, 0], [0, 0, 0], [0, 0, 0])
    with pytest.raises(ConfigError, match="inner < outer"):
        OrbitSeries("x", [0], [2], (2.4, 1.6), [], [], [])
    fig = run_figure(RunSeries("x", "isf", [0, 1, 2], [1, 1, 1], [0.1, 0.0, 0.1], [0, 1, 0], [0, 1, 0]))
    assert len(fig.axes) == 2 and math.isclose(fig.axes[0].patches[0].get_width(), 1.0)
    with pytest.raises(Exception, match="valid: .png, .svg, .pdf"):
        save_figure(fig, "/tmp/figure.gif")


def test_torque_level_recordings_plot_in_their_units_and_never_with_the_velocity_levels(tmp_path: Path,
                                                                                         capsys) -> None:
    """A torque-level run's command is a torque: its figure says N m (intervention N^2 m^2 s); recordings of the two
    levels are refused together (one bar would average rad/s and N m), in one line, before any file is written."""
    from isf_robot.plots import compare_figure

    paths = {}
    for level in ("velocity", "torque"):
        paths[level] = tmp_path / f"{level}.rrd"
        assert main(["run", "--scene", "planar", "--filter", "isf", "--level", level, "--duration", "0.3",
                     "--rrd", str(paths[level])]) == 0
    capsys.readouterr()
    torque = RunSeries(**arm_series(read_rrd(paths["torque"])[0]))
    velocity = RunSeries(**arm_series(read_rrd(paths["velocity"])[0]))
    assert (torque.unit, velocity.unit) == ("N m", "rad/s")
    assert run_figure(torque).axes[-1].get_ylabel() == "|u - u_nom| [N m]"
    assert run_figure(velocity).axes[-1].get_ylabel() == "|u - u_nom| [rad/s]"
    out = tmp_path / "mix.png"
    assert main(["plot", str(paths["torque"]), str(paths["velocity"]), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "torque and velocity-level" in err and not out.exists()
    from isf_robot.core import ConfigError
    from isf_robot.plots import StrategyBars
    from isf_robot.record.figure_data import strategy_bars

    bars = [StrategyBars(**b) for b in strategy_bars(read_rrd(paths["torque"]) + read_rrd(paths["velocity"]))]
    with pytest.raises(ConfigError, match="different units"):
        compare_figure([torque, velocity], bars)
    # the viewer's layouts label the command in the run's unit too; side by side refuses the two levels together
    from isf_robot.record.blueprints import arm_blueprint, compare_blueprint
    from isf_robot.record.errors import RecordingReadError
    from isf_robot.record.side_by_side import write_side_by_side

    def names(blueprint) -> list[str]:  # type: ignore[no-untyped-def]
        out, todo = [], [blueprint.root_container]
        while todo:
            view = todo.pop()
            todo += list(getattr(view, "contents", None) or [])
            out.append(str(getattr(view, "name", "")))
        return out

    assert "|u - u_nom| [N m]" in names(arm_blueprint(unit="N m")) and "|u - u_nom| [rad/s]" in names(arm_blueprint())
    assert "isf: |u - u_nom| [N m]" in names(compare_blueprint(["isf"], unit="N m"))
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    paths["torque"].rename(mixed / "planar-isf-seed0.rrd")
    assert main(["run", "--scene", "planar", "--filter", "cbf", "--duration", "0.3",
                 "--rrd", str(mixed / "planar-cbf-seed0.rrd")]) == 0
    with pytest.raises(RecordingReadError, match="at both levels"):
        write_side_by_side(mixed)

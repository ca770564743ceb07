"""The value labels of the comparison's bars never overlap the whiskers' caps (rendered with Agg)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="the 'plots' extra is not installed")


def _figure(values: dict[str, dict[str, list[float]]]):  # type: ignore[no-untyped-def]
    import matplotlib

    matplotlib.use("Agg")
    from isf_robot.plots.data import RunSeries, StrategyBars
    from isf_robot.plots.figures import compare_figure

    t = np.linspace(0.0, 1.0, 11)
    runs = [RunSeries(label=s, strategy=s, t=t, dt=0.1 + 0 * t, h=0.1 + 0 * t, on=np.zeros(11, bool), correction=0 * t)
            for s in values]
    bars = [StrategyBars(strategy=s, **v) for s, v in values.items()]
    fig = compare_figure(runs, bars, title="labels")
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)  # rendered with Agg, as `isf-robot plot` writes it
    return fig


CASES = {
    # whiskers reaching far above the mean; a zero-width range; a negative min h
    "spread": {"nominal": dict(duty_cycle=[0.0, 0.0, 0.0], on_switches=[0, 0, 0], intervention=[0.0, 0.0, 0.0],
                               min_barrier=[-0.02, -0.01, -0.03]),
               "cbf": dict(duty_cycle=[0.2, 0.9, 0.3], on_switches=[2, 40, 5], intervention=[0.1, 3.0, 0.2],
                           min_barrier=[0.01, 0.02, -0.005]),
               "isf": dict(duty_cycle=[0.5, 0.5, 0.5], on_switches=[3, 3, 3], intervention=[1.0, 1.1, 0.9],
                           min_barrier=[0.03, 0.05, 0.04])},
    "one episode": {"cbf": dict(duty_cycle=[0.7], on_switches=[12], intervention=[2.0], min_barrier=[0.01]),
                    "isf": dict(duty_cycle=[0.3], on_switches=[4], intervention=[2.5], min_barrier=[0.012])},
}


def _bar_containers(ax):  # type: ignore[no-untyped-def]
    from matplotlib.container import BarContainer

    return [c for c in ax.containers if isinstance(c, BarContainer)]


def _boxes(ax, fig):  # type: ignore[no-untyped-def]
    """Display-space boxes (x0, y0, x1, y1) of the bars, the whiskers and the caps of one axes."""
    renderer = fig.canvas.get_renderer()
    out = []
    for container in _bar_containers(ax):
        out += [tuple(p.get_window_extent(renderer).extents) for p in container.patches]
        if container.errorbar is None:
            continue
        _, caplines, barcols = container.errorbar.lines
        for cap in caplines:  # a '_' marker per bar: markersize wide, markeredgewidth thick [pt]
            half_w = cap.get_markersize() * fig.dpi / 72.0 / 2
            half_t = max(cap.get_markeredgewidth(), 1.0) * fig.dpi / 72.0 / 2
            for x, y in cap.get_transform().transform(cap.get_xydata()):
                out.append((x - half_w, y - half_t, x + half_w, y + half_t))
        for col in barcols:
            for seg in col.get_segments():
                (x0, y0), (x1, y1) = col.get_transform().transform(seg)
                out.append((min(x0, x1) - 0.5, min(y0, y1), max(x0, x1) + 0.5, max(y0, y1)))
    return out


@pytest.mark.parametrize("case", sorted(CASES))
def test_value_labels_clear_the_error_caps_and_stay_inside_the_axes(case: str) -> None:
    fig = _figure(CASES[case])
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    bar_axes = [ax for ax in fig.axes if ax.containers]
    assert len(bar_axes) == 4
    caps = 0
    for ax in bar_axes:
        labels = [t for t in ax.texts if t.get_text()]
        assert len(labels) == len(CASES[case])
        boxes = _boxes(ax, fig)
        caps += sum(1 for c in _bar_containers(ax) if c.errorbar is not None for cap in c.errorbar.lines[1])
        frame = ax.get_window_extent(renderer)
        for text in labels:
            tb = text.get_window_extent(renderer)
            # inside the axes: not over the title, not cut off
            assert frame.y0 - 0.5 <= tb.y0 and tb.y1 <= frame.y1 + 0.5, (ax.get_title(), text.get_text())
            for x0, y0, x1, y1 in boxes:
                clear = tb.x1 <= x0 or x1 <= tb.x0 or tb.y1 <= y0 or y1 <= tb.y0
                assert clear, f"{ax.get_title()}: label {text.get_text()} {tb.extents} overlaps {(x0, y0, x1, y1)}"
    assert (caps > 0) == (case == "spread")  # the case with whiskers has caps to clear

"""The sweep's Pareto figure: a real PNG whose drawn points are the sweep file's points, the same
file from ``sweep --plot`` and from ``plot sweep.json``, one-line errors for other JSON."""

from __future__ import annotations

import json

import pytest

from isf_robot.cli import main

pytest.importorskip("matplotlib")


def test_sweep_plot_draws_every_point_of_the_json(tmp_path, capsys):
    from matplotlib.image import imread

    from isf_robot.cli.plot import sweep_figure
    from isf_robot.plots.pareto import POINTS_GID

    out, fig1, fig2 = tmp_path / "s.json", tmp_path / "p.png", tmp_path / "q.png"
    code = main(["sweep", "--scenes", "planar", "--filters", "cbf", "isf", "--episodes", "1", "--duration", "0.6",
                 "--d-bar", "0.05", "--c", "0.05,0.2", "--blend", "0,0.02", "--quiet", "--output", str(out),
                 "--plot", str(fig1)])
    err = capsys.readouterr().err
    assert code == 0, err
    doc = json.loads(out.read_text())
    n = sum(len(sc["points"]) for sc in doc["scenes"])
    assert n == 5  # cbf + 2 x 2 isf
    assert f"{n} points of 1 scene(s)" in err
    data = fig1.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    img = imread(fig1)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200
    fig, _ = sweep_figure(doc)  # what was drawn: one offset per point, at the JSON's numbers
    drawn = [tuple(xy) for c in fig.findobj(lambda a: a.get_gid() == POINTS_GID) for xy in c.get_offsets()]
    want = [(r["duty_cycle"], r["intervention"]) for sc in doc["scenes"] for r in sc["points"]]
    assert len(drawn) == n and all(a == pytest.approx(b) for a, b in zip(sorted(drawn), sorted(want)))
    assert main(["plot", str(out), "-o", str(fig2)]) == 0
    assert fig2.read_bytes() == data  # the same figure, byte for byte, from the file


def test_plot_refuses_a_json_that_is_no_sweep_nor_tau(tmp_path, capsys):
    bad = tmp_path / "x.json"
    bad.write_text(json.dumps({"schema": "isf-robot-sweep/1", "scenes": [{"scene": "a", "points": []}]}))
    assert main(["plot", str(bad), "-o", str(tmp_path / "x.png")]) == 2
    assert "no finished points" in capsys.readouterr().err
    assert main(["sweep", "--scenes", "planar", "--plot", str(tmp_path / "x.gif")]) == 2
    assert "valid: .png, .svg, .pdf" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()

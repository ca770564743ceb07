"""Compiled arcs (satellite/orbit/fast_arcs.py) against the Python path (satellite/orbit/events.py + scipy's DOP853)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("numba")

from isf_robot.core import Linear  # noqa: E402
from satellite.control.contact import make_contact  # noqa: E402
from satellite.control.triggers import (  # noqa: E402
    CONTACT,
    RDOT,
    XI,
    BandTriggers,  # noqa: E402
    H,
)
from satellite.gravity.fields import DEFAULT_GRAVITY, load_field  # noqa: E402
from satellite.orbit.events import event, integrate  # noqa: E402
from satellite.orbit.fast_arcs import FastArcs, jit_enabled  # noqa: E402
from satellite.orbit.model import OrbitModel  # noqa: E402
from satellite.shape.mesh_surface import load_surface  # noqa: E402

KW = dict(rtol=1e-10, atol=1e-12, max_step=1200.0, min_dt=1e-2)


@pytest.fixture(scope="module")
def setup():  # type: ignore[no-untyped-def]
    if not jit_enabled():
        pytest.skip("compiled arcs switched off (ISF_ROBOT_JIT=0)")
    model = OrbitModel(load_field(DEFAULT_GRAVITY), body_phase=0.7)
    trig = BandTriggers(model, Linear(2.6e-4), 0.0, accel_bound=model.accel_bound(samples=400))
    watch = make_contact(model, load_surface(), samples=400, slow_samples=5)
    fast = FastArcs.make(model, trig, watch)
    assert fast is not None
    return model, trig, watch, fast


def _state(model: OrbitModel, r_over_R: float, speed: float, incl: float) -> np.ndarray:
    r = r_over_R * model.R
    v = speed * math.sqrt(model.mu / r)
    return np.array([r, 0.0, 0.0, 0.0, v * math.cos(incl), v * math.sin(incl)])


def test_compiled_right_hand_side_is_the_models(setup) -> None:  # type: ignore[no-untyped-def]
    from satellite.orbit.kernel_parts import rhs

    model, _, _, fast = setup
    rng = np.random.default_rng(3)
    u = rng.normal(size=(300, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    pts = u * rng.uniform(1.6, 2.4, size=300)[:, None] * model.R
    tips = np.array([[s * x, 0.0, 0.0] for s in (-1, 1) for x in (265.0, 280.0, 300.0, 320.0)])  # in the fine boxes
    out = np.empty(6)
    for k, p in enumerate(np.vstack([pts, tips])):
        y = np.concatenate([p, rng.normal(size=3) * 0.1])
        t = float(rng.uniform(0, 1e6))
        rhs(t, y, out, fast.fp, fast.ext, fast.box_o, fast.box_n, fast.coef)
        np.testing.assert_allclose(out, model.truth_rhs(t, y), rtol=1e-12, atol=1e-20, err_msg=str(k))
    # outside the table's radii: the table's continuation (gravity.table.shell_continued); in the end cells, below (r_lo) and above (r_hi), near the tips' fine boxes, far out
    far = [u[k] * f * model.R for k, f in enumerate((1.44, 1.47, 1.52, 1.56, 2.44, 2.48, 2.53, 2.6, 3.0))]
    far += [np.array([s * 245.0, 0.0, 0.0]) for s in (-1, 1)]
    for k, p in enumerate(far):
        assert not model.field.fast_radii[0] <= np.linalg.norm(p) <= model.field.fast_radii[1]
        y = np.concatenate([p, rng.normal(size=3) * 0.1])
        rhs(0.0, y, out, fast.fp, fast.ext, fast.box_o, fast.box_n, fast.coef)
        np.testing.assert_allclose(out, model.truth_rhs(0.0, y), rtol=1e-12, atol=1e-20, err_msg=str(k))


def _events(trig, watch, xi_terminal: bool = True):  # type: ignore[no-untyped-def]
    rates = trig.rates()
    return [event(trig.xi, xi_terminal, -1.0, rates["xi"], trig.xi_batch, (XI, 0.0, None)),
            event(trig.r_dot, False, 0.0, rates["apsis"], trig.r_dot_batch, (RDOT, 0.0, None)),
            event(trig.h, False, -1.0, rates["h"], trig.h_batch, (H, 0.0, None)),
            event(watch.g, False, 0.0, watch.rate, watch.batch, (CONTACT, 0.0, None))]


# (disturbance scale, speed / circular, inclination, hours, event tolerance [s], position tolerance [m])
ARCS = [
    # Kepler through the compiled path (the table's part scaled by 0): both integrate a smooth flow, so they
    # stay within rounding of each other (measured 1e-7 m, events 2e-6 s after 10 h)
    (0.0, 0.95, 1.2, 10.0, 1e-4, 1e-6), (0.0, 1.03, 0.8, 10.0, 1e-4, 1e-6),
    # the table field: differences of rounding grow along the orbit (measured: 1e-5 m after 3.5 h, an apsis
    # where r . v is flat moves by ~1 ms; equatorial orbits that graze the tips diverge much faster: not here)
    (1.0, 1.0, 1.2, 3.5, 2e-2, 1e-3), (1.0, 0.95, 1.5, 3.5, 2e-2, 1e-3),
]


@pytest.mark.parametrize("scale, speed, incl, hours, ev_tol, pos_tol", ARCS)
def test_same_arc_and_events_as_the_python_path(setup, scale, speed, incl, hours, ev_tol,  # type: ignore[no-untyped-def]
                                                pos_tol) -> None:
    model, trig, watch, _ = setup
    if scale != 1.0:
        model = OrbitModel(model.field, body_phase=model.body_phase, disturbance_scale=scale)
    fast = FastArcs.make(model, trig, watch)
    assert fast is not None
    y0 = _state(model, 2.0, speed, incl)
    evs = _events(trig, watch, xi_terminal=False)
    t1 = hours * 3600.0
    got = fast.integrate(0.0, t1, y0, evs, dense=True, scan=True, **KW)
    ref = integrate(model.truth_rhs, 0.0, t1, y0, evs, dense=True, **KW)
    assert got is not None and got.status == ref.status == 0
    assert sum(len(a) for a in got.t_events) >= 2
    for k, (a, b) in enumerate(zip(got.t_events, ref.t_events)):
        assert len(a) == len(b), k
        np.testing.assert_allclose(a, b, rtol=0, atol=ev_tol)
    assert abs(len(got.t) - len(ref.t)) <= 3
    tt = np.linspace(0.0, t1, 101)
    tol = np.array([pos_tol] * 3 + [pos_tol * 1e-4] * 3)[:, None]  # m, m/s
    assert (np.abs(got.sol(tt) - ref.sol(tt)) <= tol).all()
    assert (np.abs(got.sol(float(tt[37])) - ref.sol(float(tt[37]))) <= tol[:, 0]).all()
    assert got.t[-1] == t1
    np.testing.assert_allclose(got.y[:, -1], got.sol(t1), rtol=0, atol=1e-9)


def test_a_dip_between_step_points_is_found(setup) -> None:  # type: ignore[no-untyped-def]
    """``h - c`` dips below 0 around the inner apsis, inside one step: found only by the scan (both paths)."""
    model, trig, watch, fast = setup
    y0 = _state(model, 2.0, 0.95, 1.5)
    t1 = 3.5 * 3600.0
    apsis = fast.integrate(0.0, t1, y0, _events(trig, watch, xi_terminal=False)[1:2], dense=False, scan=True, **KW)
    assert apsis is not None
    k = int(np.argmin([trig.h(0, y) for y in apsis.y_events[0]]))
    t_apo, y_apo = float(apsis.t_events[0][k]), apsis.y_events[0][k]
    assert 0.0 < t_apo < t1
    h_apo = trig.h(t_apo, y_apo)
    near = [j for j in range(len(apsis.t) - 1) if apsis.t[j] < t_apo < apsis.t[j + 1]][0]
    h_steps = min(trig.h(0, apsis.y[:, near]), trig.h(0, apsis.y[:, near + 1]))
    c = h_apo + 0.3 * (h_steps - h_apo)  # above h at the apsis, below h at both step points
    t1 = float(apsis.t[near + 1])  # the same steps up to here, the arc ends at the dip's step
    assert min(trig.h(0, y) for y in apsis.y[:, : near + 2].T) > c
    rates = trig.rates()

    def dip(t: float, y: np.ndarray) -> float:
        return trig.h(t, y) - c

    def dip_batch(t: np.ndarray, y: np.ndarray) -> np.ndarray:
        return trig.h_batch(t, y) - c

    scanned = [event(dip, True, -1.0, rates["h"], dip_batch, (H, c, None))]
    got = fast.integrate(0.0, t1, y0, scanned, dense=False, scan=True, **KW)
    ref = integrate(model.truth_rhs, 0.0, t1, y0, scanned, **KW)
    blind = fast.integrate(0.0, t1, y0, scanned, dense=False, scan=False, **KW)
    assert got is not None and blind is not None
    assert got.status == ref.status == 1 and blind.status == 0  # unscanned: the dip goes unseen
    assert got.t[-1] == pytest.approx(ref.t[-1], abs=0.5)  # a shallow minimum: the root moves with rounding
    assert got.t[-1] < t_apo and abs(dip(0, got.y[:, -1])) < 1e-9 * c and abs(dip(0, ref.y[:, -1])) < 1e-9 * c
    assert got.scan_points > 0


def test_arcs_outside_the_table_stay_compiled(setup) -> None:  # type: ignore[no-untyped-def]
    model, trig, watch, fast = setup
    y0 = _state(model, 2.35, 1.3, 0.2)  # leaves the band outward, then the table's radii
    evs = _events(trig, watch)[1:]
    t1 = 3 * 3600.0
    got = fast.integrate(0.0, t1, y0, evs, dense=True, scan=True, **KW)
    ref = integrate(model.truth_rhs, 0.0, t1, y0, evs, dense=True, **KW)  # the same continuation, in Python
    assert got is not None and got.status == ref.status == 0
    assert np.linalg.norm(got.y[:3], axis=0).max() > 1.2 * model.field.grid.r_hi  # beyond the end nodes
    tt = np.linspace(0.0, t1, 31)
    # the two paths choose their own steps (their error estimates differ by rounding near the acceptance threshold,
    # so the steps fall at other times: 20 each over these 3 h), so they agree to the integrator's tolerance
    # accumulated over the arc, not to rounding: within 1e-7 of the radius (measured 2.3e-8 on an Intel Xeon,
    # 1.7e-5 m at 744 m)
    r = np.linalg.norm(ref.sol(tt)[:3], axis=0)
    assert (np.abs(got.sol(tt) - ref.sol(tt))[:3] <= 1e-7 * r).all()
    assert fast.integrate(5.0, 5.0, y0, evs, dense=True, scan=True, **KW) is None  # empty arc: Python's rules
    uncoded = [event(trig.h, False, -1.0)]
    assert fast.integrate(0.0, 100.0, y0, uncoded, dense=True, scan=True, **KW) is None


def test_greedy_run_agrees_with_the_python_path(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from satellite.orbit.model import InitialOrbit
    from satellite.orbit.simulate import simulate

    if not jit_enabled():
        pytest.skip("compiled arcs switched off")
    model = OrbitModel(load_field(DEFAULT_GRAVITY))
    kw = dict(initial=InitialOrbit(seed=2), model=model, contact="count", miet_samples=50)
    fast = simulate("greedy", 6.0, **kw)  # type: ignore[arg-type]
    monkeypatch.setenv("ISF_ROBOT_JIT", "0")
    slow = simulate("greedy", 6.0, **kw)  # type: ignore[arg-type]
    # the same impulses; their times agree to 1e-8 s until ~4.3 h, when this orbit nears the body's tip and
    # rounding differences e-fold every ~2 minutes (measured: 0.6 s apart at 5.6 h, both paths' RHS equal to
    # 4e-16): the run's figures agree to about 1e-4
    assert fast.triggers == slow.triggers > 0
    assert fast.min_h == pytest.approx(slow.min_h, rel=1e-3)
    assert fast.total_dv == pytest.approx(slow.total_dv, rel=1e-3)
    ft, st = np.array([e.t for e in fast.events]), np.array([e.t for e in slow.events])
    np.testing.assert_allclose(ft[ft < 4 * 3600.0], st[ft < 4 * 3600.0], rtol=0, atol=1e-5)
    np.testing.assert_allclose(ft, st, rtol=0, atol=5.0)


class _ExactOutside:
    """The committed table inside its radii and the exact field outside them (the table's answer before it had a
    continuation); no compiled form, so a run with it integrates in Python."""

    degree = None
    model_name = "table, exact outside"

    def __init__(self, table) -> None:  # type: ignore[no-untyped-def]
        self.table, self.exact = table, table.exact
        self.r_ref_m, self.gm, self.fast_radii = table.r_ref_m, table.gm, table.fast_radii
        self.outside = 0

    def _in(self, p: np.ndarray) -> np.ndarray:
        r = np.linalg.norm(p, axis=1)
        return (r >= self.fast_radii[0]) & (r <= self.fast_radii[1])

    def acceleration_batch(self, pts):  # type: ignore[no-untyped-def]
        p = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        ok = self._in(p)
        out = np.empty_like(p)
        out[ok] = self.table.acceleration_batch(p[ok])
        if (~ok).any():
            self.outside += int((~ok).sum())
            out[~ok] = self.exact.acceleration(p[~ok])
        return out

    def acceleration(self, p):  # type: ignore[no-untyped-def]
        q = np.asarray(p, dtype=np.float64).reshape(3)
        return self.table.acceleration(p) if self._in(q[None])[0] else self.acceleration_batch(q[None])[0]


def test_alpha_x100_run_is_fast_and_counts_as_with_the_exact_field() -> None:
    """At 100x the default alpha gain DOP853's stage points leave the table's radii (r/R 1.48-2.54); the table's
    continuation answers there inside the compiled arc. Over 24 h: the same counts as a run whose field is the
    exact one outside the radii (2400 h, where the orbit is chaotic: REPRODUCTION.md)."""
    import time

    from satellite.control.controller import ControlParams
    from satellite.orbit.model import InitialOrbit
    from satellite.orbit.simulate import simulate

    if not jit_enabled():
        pytest.skip("compiled arcs switched off (ISF_ROBOT_JIT=0)")
    table = load_field(DEFAULT_GRAVITY)
    gain = 100.0 * OrbitModel(table).mean_motion_centre()
    init = InitialOrbit(seed=0)
    simulate("greedy", 0.5, initial=init, model=OrbitModel(table))  # compiled once (numba's cache), not timed
    t0 = time.perf_counter()
    fast = simulate("greedy", 24.0, initial=init, model=OrbitModel(table), control=ControlParams(alpha_gain=gain),
                    contact="count")
    wall = time.perf_counter() - t0
    ref_field = _ExactOutside(table)
    ref = simulate("greedy", 24.0, initial=init, model=OrbitModel(ref_field), control=ControlParams(alpha_gain=gain),
                   contact="count")
    assert ref_field.outside > 0  # the run's stage points did leave the radii
    a, b = fast.summary(), ref.summary()
    assert a["triggers"] == b["triggers"] > 3 and a["kinds"] == b["kinds"]
    for key in ("band_exits", "surface_contacts", "envelope_passes", "min_interval_binds", "min_interval_overrides"):
        assert a[key] == b[key], key
    assert a["min_h"] == pytest.approx(b["min_h"], rel=1e-4)
    assert a["total_dv"] == pytest.approx(b["total_dv"], rel=1e-4)
    assert 1.6 <= a["r_min_over_R"] and a["r_max_over_R"] <= 2.4
    assert wall < 20.0, wall  # ~1-2 s here; 2400 h at x100: benchmarks/satellite_alpha.py (BENCHMARKS.md)

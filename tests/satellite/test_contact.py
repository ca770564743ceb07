"""Surface contact in the dynamics: the radius envelope, the contact event, and runs that stop or count."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import ConfigError
from satellite.control.contact import ContactWatch, RadiusEnvelope, ellipsoid_mesh
from satellite.orbit.model import InitialOrbit
from satellite.orbit.simulate import simulate
from satellite.shape.surfaces import EllipsoidSurface


def directions(n: int, seed: int) -> np.ndarray:
    u = np.random.default_rng(seed).normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1)[:, None]


def lumpy_body(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A star-shaped body with bumps (vertices of an ellipsoid net moved along their radii)."""
    v, f = ellipsoid_mesh(np.array([120.0, 80.0, 60.0]), 24)
    u = v / np.linalg.norm(v, axis=1)[:, None]
    bump = 1.0 + 0.15 * np.sin(3 * np.arctan2(u[:, 1], u[:, 0])) * np.cos(2 * np.arcsin(u[:, 2]))
    return v * bump[:, None], f


def ray_radius(v: np.ndarray, f: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Largest distance at which each unit ray from the origin meets a triangle (Moller-Trumbore)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e1, e2 = b - a, c - a
    out = np.zeros(len(u))
    for k, d in enumerate(u):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = -a
        bu = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        bv = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (bu >= 0) & (bv >= 0) & (bu + bv <= 1) & (t > 0)
        out[k] = t[hit].max()
    return out


def test_envelope_bounds_the_surface_radius_and_its_slope() -> None:
    v, f = lumpy_body()
    env = RadiusEnvelope(v, f, n_lat=45)
    u = directions(400, 1)
    exact = ray_radius(v, f, u)
    r = env.radius(u)
    assert np.all(r >= exact), float((exact - r).max())
    assert float(np.mean(r - exact)) < 0.15 * float(np.mean(exact))  # conservative, not useless
    # the slope bound holds between nearby directions (continuity with a known modulus)
    w = u + 0.02 * directions(400, 2)
    w /= np.linalg.norm(w, axis=1)[:, None]
    ang = np.arccos(np.clip(np.einsum("ij,ij->i", u, w), -1, 1))
    assert np.all(np.abs(env.radius(w) - r) <= env.slope * ang + 1e-9)
    # continuity across longitude +-180 deg and at the poles
    eps = 1e-9
    a = env.radius(np.array([[-1.0, eps, 0.3], [-1.0, -eps, 0.3], [eps, 0.0, 1.0], [-eps, eps, 1.0]]))
    assert a[0] == pytest.approx(a[1], abs=1e-6) and a[2] == pytest.approx(a[3], abs=1e-6)


def test_ellipsoid_envelope_is_above_the_ellipsoid() -> None:
    e = EllipsoidSurface([200.0, 100.0, 70.0])
    env = RadiusEnvelope.from_surface(e, n_lat=45)
    u = directions(5000, 3)
    assert np.all(env.radius(u) >= e.surface_radius(u))


def test_first_contact_of_a_straight_pass_through_a_sphere() -> None:
    sphere = EllipsoidSurface([100.0, 100.0, 100.0])
    watch = ContactWatch(sphere, RadiusEnvelope.from_surface(sphere, n_lat=45), 0.0, 0.0, 1e-4, step_s=1.0)

    def line(t: object) -> np.ndarray:  # x = 60 m, y = -300 + 1 m/s t: enters the sphere at y = -80
        tt = np.asarray(t, dtype=float)
        return np.stack([60.0 + 0 * tt, -300.0 + tt, 0 * tt, 0 * tt, 1 + 0 * tt, 0 * tt])

    tc, clear = watch.first_contact(line, 150.0, 450.0)
    assert tc == pytest.approx(300.0 - math.sqrt(100.0**2 - 60.0**2), abs=1e-5)
    assert clear == pytest.approx(60.0 - 100.0, abs=0.5)  # radial clearance at closest approach
    assert watch.first_contact(line, 0.0, 150.0)[0] is None
    assert watch.passes(0.0, 10.0, -1.0, np.array([2.0, 5.0])) == [(0.0, 2.0), (5.0, 10.0)]


LONG_BODY = EllipsoidSurface([330.0, 150.0, 105.0], name="test body reaching 2.04 R")


@pytest.fixture(scope="module")
def contact_runs() -> dict[str, object]:
    kw = dict(initial=InitialOrbit(seed=2), miet_samples=200, contact_surface=LONG_BODY)
    return {m: simulate("greedy", 20.0, contact=m, **kw) for m in ("off", "count", "stop")}


def test_count_reports_contacts_without_changing_the_orbit(contact_runs) -> None:  # type: ignore[no-untyped-def]
    off, count = contact_runs["off"], contact_runs["count"]
    assert off.contact is None
    c = count.contact
    assert c["surface_contacts"] >= 1 and c["min_pass_clearance_m"] < 0 and not c["contact_stopped"]
    assert c["envelope_passes"] >= c["surface_contacts"]
    assert (count.triggers, count.min_h, count.total_dv) == (off.triggers, off.min_h, off.total_dv)
    assert {"surface_contacts", "first_contact_h"} <= set(count.summary())


def test_stop_ends_the_run_on_the_surface(contact_runs) -> None:  # type: ignore[no-untyped-def]
    count, stop = contact_runs["count"], contact_runs["stop"]
    c = stop.contact
    assert c["contact_stopped"] and c["surface_contacts"] == 1
    assert c["first_contact_h"] == pytest.approx(count.contact["first_contact_h"], abs=1e-9)
    assert stop.simulated_h == pytest.approx(c["first_contact_h"], abs=1e-12) and stop.simulated_h < 20.0
    assert stop.triggers <= count.triggers
    # the counting run's physical part is the stopping run: the same impulses, up to the same contact
    assert c["physical_h"] == pytest.approx(c["first_contact_h"], abs=1e-12)
    pc = count.contact
    assert pc["physical_h"] == pytest.approx(c["first_contact_h"], abs=1e-9)
    assert pc["physical_h"] < count.simulated_h
    assert pc["triggers_physical"] == stop.triggers < count.triggers
    assert pc["total_dv_physical"] == pytest.approx(stop.total_dv, rel=1e-12)
    assert c["triggers_physical"] == stop.triggers


def test_a_run_without_contact_is_physical_to_its_end() -> None:
    res = simulate("greedy", 6.0, initial=InitialOrbit(seed=2), miet_samples=50, contact="count",
                   contact_surface=EllipsoidSurface([100.0, 90.0, 80.0], name="small body"))
    c = res.contact
    assert c["surface_contacts"] == 0 and c["first_contact_h"] is None
    assert c["physical_h"] == pytest.approx(res.simulated_h) and c["triggers_physical"] == res.triggers >= 1


def test_unknown_contact_mode_is_refused() -> None:
    with pytest.raises(ConfigError, match="contact must be one of"):
        simulate("greedy", 1.0, contact="bounce")


def test_contact_event_and_its_rate_bound_along_truth_arcs() -> None:
    """``g`` of one state, of many and of the compiled formula agree; the rate bound exceeds every finite difference."""
    from scipy.integrate import solve_ivp

    from satellite.gravity.fields import load_field
    from satellite.orbit.model import OrbitModel

    model = OrbitModel(load_field("table"), body_phase=0.4)
    v, f = lumpy_body(2)
    v = v * (1.35 * model.R / np.linalg.norm(v, axis=1).max())  # a body reaching into the band
    env = RadiusEnvelope(v, f, n_lat=30)
    watch = ContactWatch(EllipsoidSurface((1.0, 1.0, 1.0)), env, model.body_phase, model.omega,
                         accel_bound=2.0 * model.accel_bound(samples=400))
    rng = np.random.default_rng(5)
    seen_inside = False
    for _ in range(5):
        u = directions(1, int(rng.integers(1 << 30)))[0]
        w = np.cross(u, rng.normal(size=3))
        w /= np.linalg.norm(w)
        r = 1.45 * model.R
        y0 = np.concatenate([r * u, 0.9 * math.sqrt(model.mu / r) * w])
        sol = solve_ivp(model.truth_rhs, (0.0, 3000.0), y0, method="DOP853", rtol=1e-11, atol=1e-12,
                        dense_output=True)
        ts = np.linspace(0.0, sol.t[-1], 1501)
        ys = sol.sol(ts)
        g = watch.batch(ts, ys)
        np.testing.assert_array_equal(g[::100], [watch.g(t, y) for t, y in zip(ts[::100], ys.T[::100])])
        r = np.linalg.norm(ys[:3], axis=0)
        body = np.array([watch.body_point(t, y)[0] for t, y in zip(ts, ys.T)])
        cont = r - env.radius(body)  # g without its shortcut beyond max r_env (g <= cont, equal where g < 0)
        assert np.all(g <= cont + 1e-9) and np.array_equal(g < 0, cont < 0)
        seen_inside |= bool((r <= env.max_radius).any())
        for step in (1, 25, 300):
            a, b = slice(0, -step, step), slice(step, None, step)
            dt = ts[step] - ts[0]
            bound = watch.rate(ys[:, a], ys[:, b], dt) * dt
            out = (cont[a] >= 0) & (cont[b] >= 0)  # the bound is stated where g >= 0 (where the scan needs it)
            bad = np.flatnonzero(out & (np.abs(cont[b] - cont[a]) > bound))
            assert not len(bad), (step, cont[a][bad[:3]], cont[b][bad[:3]], bound[bad[:3]])
            one = [float(watch.rate(ys[:, i], ys[:, i + step], dt)) for i in range(0, len(ts) - step, 7 * step)]
            np.testing.assert_allclose(one, bound[::7] / dt, rtol=1e-12)  # the formula for one interval
    assert seen_inside  # the arcs pass below the envelope's top, where its turn term counts

"""The robust term of the greedy trigger and the post-jump condition, against the paper's equation.

The paper's trigger (eq. greedy_cond) is ``Xi(x) = LF h(x) - |dh/dx| d_bar + alpha(h(x))``. For the
band barrier ``h = (0.4 R)^2 - (|p| - 2R)^2`` along the Kepler flow ``F = [v, -mu p / |p|^3]``,
:func:`xi_paper` below restates it from the vectors (the gradient ``dh/dx`` and its norm, ``F``), not
from the code's scalar shortcut ``2 |r - 2R|``, so each implementation is checked against the
equation: the scalar ``BandTriggers.xi``, the event scan's ``BandTriggers.xi_batch`` and the compiled
event function ``satellite.orbit.kernel_parts.g_event`` (the compiled arcs' ``Xi``), all with ``d_bar > 0``
(where the robust term's sign shows), and the post-jump condition ``Xi(G(x, K(x))) >= c`` (paper,
eq. control_jump_cond) on its own: at random states near the band's edges and after every impulse
of a short run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import Linear
from satellite.control.controller import ControlParams, SafeguardingController, jump_map, resolve_control
from satellite.control.triggers import BandTriggers
from satellite.orbit.model import InitialOrbit, OrbitModel

D_BARS = (1e-5, 1e-4, 1e-3)  # m/s^2: the robust term 2 |r - 2R| d_bar is up to 1.3e-3 .. 0.13 m^2/s in the band

POST_TOL = 1e-6
"""Tolerance of ``Xi(x+) >= c`` [m^2/s]. ``c`` comes from the post-jump ``Xi`` sampled on 4001 radii: between
them it dips below the sampled minimum by <= 1.2e-7 m^2/s (measured on 400001 radii, c_fraction = 1). A sign
error of the robust term moves the post-jump ``Xi`` by ``4 |r - 2R| d_bar``, >= 1e-2 m^2/s in these cases."""


@pytest.fixture(scope="module")
def model() -> OrbitModel:
    return OrbitModel()  # the default (tabulated) field: the one the compiled arcs run


def xi_paper(x: np.ndarray, R: float, mu: float, gain: float, d_bar: float) -> float:
    """eq. greedy_cond for the band barrier and the Kepler flow, from the vectors."""
    p, v = x[:3], x[3:]
    r = math.sqrt(float(p @ p))
    h = (0.4 * R) ** 2 - (r - 2.0 * R) ** 2
    grad = np.concatenate([-2.0 * (r - 2.0 * R) * p / r, np.zeros(3)])  # dh/dx (h depends on p only)
    flow = np.concatenate([v, -mu * p / r**3])
    return float(grad @ flow) - float(np.linalg.norm(grad)) * d_bar + gain * h


def random_states(model: OrbitModel, n: int, seed: int, bands: tuple[tuple[float, float], ...] = ((1.6, 2.4),)
                  ) -> np.ndarray:
    """``n`` states, shape (n, 6): radius uniform in the given bands [R], any direction, bound-orbit speeds."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array(bands).T
    k = rng.integers(len(bands), size=n)
    r = rng.uniform(lo[k], hi[k]) * model.R
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    speed = rng.uniform(0.6, 1.3, size=n) * np.sqrt(model.mu / r)
    return np.hstack([u * r[:, None], w * speed[:, None]])


def compiled_xi(model: OrbitModel, trig: BandTriggers):  # type: ignore[no-untyped-def]
    """The compiled event function ``Xi`` with the run's packed band parameters, as ``x -> float``.

    ``None`` when the compiled arcs are off (``ISF_ROBOT_JIT=0``): the runs do not use it then.
    """
    from satellite.control.triggers import XI
    from satellite.orbit.fast_arcs import FastArcs, jit_enabled

    if not jit_enabled():
        return None
    from satellite.orbit.kernel_parts import g_event

    fast = FastArcs.make(model, trig, None)
    assert fast is not None
    tp = np.array([0.0, 0.0, 1.0, 0.0])  # (no maneuver fit: unused by Xi)
    return lambda x: float(g_event(XI, 0.0, 0.0, np.ascontiguousarray(x), fast.bp, fast.cp, fast.env, tp))


def implementations(model: OrbitModel, gain: float, d_bar: float) -> dict[str, object]:
    """Each implementation of ``Xi`` as ``states (n, 6) -> (n,)`` (the compiled one when the arcs run compiled)."""
    trig = BandTriggers(model, Linear(gain), d_bar)
    comp = compiled_xi(model, trig)
    out: dict[str, object] = {
        "scalar": lambda xs: np.array([trig.xi(0.0, x) for x in xs]),
        "batch": lambda xs: trig.xi_batch(np.zeros(len(xs)), xs.T.copy()),
    }
    if comp is not None:
        out["compiled"] = lambda xs: np.array([comp(x) for x in xs])
    return out


def test_the_oracles_gradient_is_the_barriers() -> None:
    """xi_paper's dh/dx is the gradient of h (central differences), so the oracle is the equation."""
    R, mu = 160.0, 2.3
    rng = np.random.default_rng(1)
    for _ in range(20):
        x = np.concatenate([rng.normal(size=3) * 1.2 * R, rng.normal(size=3) * 0.05])

        def h(q: np.ndarray) -> float:
            return (0.4 * R) ** 2 - (float(np.linalg.norm(q[:3])) - 2 * R) ** 2

        eps = 1e-4
        grad = np.array([(h(x + eps * e) - h(x - eps * e)) / (2 * eps) for e in np.eye(6)])
        lfh = float(grad @ np.concatenate([x[3:], -mu * x[:3] / np.linalg.norm(x[:3]) ** 3]))
        d_bar, gain = 1e-3, 3e-4
        want = lfh - float(np.linalg.norm(grad)) * d_bar + gain * h(x)
        assert xi_paper(x, R, mu, gain, d_bar) == pytest.approx(want, rel=1e-7, abs=1e-9)


@pytest.mark.parametrize("d_bar", D_BARS)
def test_scalar_batch_and_compiled_xi_are_the_papers_with_a_disturbance_bound(model: OrbitModel, d_bar: float) -> None:
    gain = model.mean_motion_centre()
    xs = random_states(model, 300, seed=11)
    want = np.array([xi_paper(x, model.R, model.mu, gain, d_bar) for x in xs])
    for name, fn in implementations(model, gain, d_bar).items():
        got = fn(xs)  # type: ignore[operator]
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12, err_msg=f"{name}, d_bar {d_bar:g}")


def test_the_robust_term_lowers_xi_by_exactly_two_dr_d_bar(model: OrbitModel) -> None:
    """``Xi(x; 0) - Xi(x; d_bar) = |dh/dx| d_bar = 2 |r - 2R| d_bar >= 0``: Xi falls as d_bar grows, by that term."""
    gain = model.mean_motion_centre()
    xs = random_states(model, 200, seed=12)
    dr = np.abs(np.linalg.norm(xs[:, :3], axis=1) - 2.0 * model.R)
    assert dr.max() > 0.35 * model.R  # states across the band, the term up to its largest
    base = {name: fn(xs) for name, fn in implementations(model, gain, 0.0).items()}  # type: ignore[operator]
    prev = base
    for d_bar in D_BARS:
        now = {name: fn(xs) for name, fn in implementations(model, gain, d_bar).items()}  # type: ignore[operator]
        for name in base:
            drop = base[name] - now[name]
            np.testing.assert_allclose(drop, 2.0 * dr * d_bar, rtol=1e-8, atol=1e-12, err_msg=f"{name}, d_bar {d_bar:g}")
            assert np.all(now[name] <= prev[name]), (name, d_bar)  # a larger bound never raises Xi
        prev = now


# (d_bar [m/s^2], c_fraction): the default margin (half the smallest post-jump Xi) with a large bound, and the
# sharpest margin (c = that smallest value) with a small one
POST_CASES = [(3e-3, 0.5), (1e-4, 1.0), (0.0, 1.0)]


@pytest.mark.parametrize("d_bar, c_fraction", POST_CASES)
def test_post_jump_xi_is_at_least_c_near_the_band_edges(model: OrbitModel, d_bar: float, c_fraction: float) -> None:
    """The paper's controller K at states near both edges (and across the band): ``Xi(G(x, K(x))) >= c``."""
    res = resolve_control(model, ControlParams(d_bar=d_bar, c_fraction=c_fraction))
    K = SafeguardingController(model)
    edges = ((1.6, 1.65), (2.35, 2.4))
    xs = np.vstack([random_states(model, 300, seed=13, bands=edges), random_states(model, 100, seed=14),
                    [[b * model.R, 0.0, 0.0, 0.0, 0.9 * math.sqrt(model.mu / (b * model.R)), 0.0]
                     for b in (1.6, 2.4, res.argmin_r_over_R)]])  # on the edges, and where the minimum was found
    low = math.inf
    for x in xs:
        xp = jump_map(x, K(0.0, x))
        np.testing.assert_array_equal(xp[:3], x[:3])  # the jump moves the velocity only: h(x+) = h(x) >= 0
        xi_after = xi_paper(xp, model.R, model.mu, res.alpha_gain, d_bar)
        assert xi_after >= res.c - POST_TOL, (np.linalg.norm(x[:3]) / model.R, xi_after, res.c)
        low = min(low, xi_after)
    if c_fraction == 1.0:  # the margin is the smallest post-jump Xi: some state comes close to it
        assert low - res.c < 0.05 * res.c


@pytest.fixture(scope="module")
def disturbed_run():  # type: ignore[no-untyped-def]
    from satellite.orbit.simulate import simulate

    return simulate("greedy", 24.0, initial=InitialOrbit(seed=0), control=ControlParams(d_bar=1e-3), miet_samples=50)


def test_every_impulse_of_a_run_fires_at_xi_zero_and_leaves_xi_at_least_c(disturbed_run) -> None:  # type: ignore[no-untyped-def]
    """A 24 h greedy run with d_bar = 1e-3: each impulse where the paper's Xi is 0, and Xi(x+) >= c after it."""
    res = disturbed_run
    s = res.settings
    assert s["d_bar"] == 1e-3 and res.triggers >= 5
    dr = [abs(float(np.linalg.norm(j.x_before[:3])) - 2.0 * s["R_m"]) for j in res.events]
    assert min(dr) > 10.0  # m: the robust term (>= 0.02 m^2/s here) is in every impulse's Xi
    for j in res.events:
        xi_before = xi_paper(j.x_before, s["R_m"], s["mu"], s["alpha_gain"], s["d_bar"])
        assert abs(xi_before) < 1e-6, (j.index, xi_before)  # located on the paper's Xi = 0
        np.testing.assert_array_equal(j.x_after[:3], j.x_before[:3])
        xi_after = xi_paper(j.x_after, s["R_m"], s["mu"], s["alpha_gain"], s["d_bar"])
        assert xi_after >= s["c"] - POST_TOL, (j.index, xi_after, s["c"])


def test_compiled_arcs_key_their_cache_on_the_core_formulas_they_call() -> None:
    """The arcs' ``Xi`` compiles the core's ``robust_slack``: an edit of the core must not load a stale kernel.

    numba checks only the kernel's own file before loading it from its disk cache; the satellite's kernels
    are stamped with every source file of the satellite and of the core instead.
    """
    pytest.importorskip("numba")
    from satellite.orbit import kernel_parts

    stamp = kernel_parts.g_event._cache._cache_file._source_stamp
    names = {entry[0] for entry in stamp}
    assert {"core/robust.py", "core/triggers.py", "control/triggers.py", "orbit/kernel_parts.py"} <= names
    import satellite.control.triggers as trig
    from isf_robot.core.robust import robust_slack

    assert trig.band_xi(1.5, 2.5, 2.0, 0.1, 0.25) == robust_slack(1.5, 0.0, 1.0, 0.1, 0.25)

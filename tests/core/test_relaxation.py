"""The intermittent filter's relaxation policy: infeasible promotions are relaxed to the robust
condition, the safety rows are never relaxed, and a still-infeasible problem raises with evidence."""

import numpy as np
import pytest

from isf_robot.core import InfeasibleFilterError, IntermittentSafetyFilter, LieData, Linear


def _lie(h, lg, names=("a", "b")):
    h = np.asarray(h, float)
    lg = np.asarray(lg, float)
    return LieData(h, np.zeros_like(h), lg, np.linalg.norm(lg, axis=1), tuple(names))


def test_infeasible_promotion_is_relaxed_but_the_safety_rows_are_kept():
    # two barriers pushing u in opposite directions: dh_a/dt = u, dh_b/dt = -u, h = 0.1 each.
    # Promotion (u >= 0.3 and -u >= 0.3) is impossible; the robust rows give u in [-0.1, 0.1].
    f = IntermittentSafetyFilter(Linear(1.0), c=1.0, b=0.3)
    step = f.step_lie(0.0, _lie([0.1, 0.1], [[1.0], [-1.0]]), np.array([0.5]))
    # Xi_on = (0.5 + 0.1, -0.5 + 0.1): on, both below c -> both promoted, then relaxed
    assert step.on and step.event is not None and step.event.kind == "on"
    assert step.relaxed == ("a", "b")
    assert step.qp.relaxed == (0, 1)
    assert not step.fallback and step.qp.ok
    # the robust condition still holds: nearest point of [-0.1, 0.1] to u_nom = 0.5
    assert step.u[0] == pytest.approx(0.1, abs=1e-8)
    assert f.qp_solves == 2  # promoted solve, then the robust one


def test_feasible_promotion_is_not_relaxed():
    f = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=0.2)
    s = f.step_lie(0.0, _lie([0.1, 2.0], [[1.0], [-1.0]]), np.array([-0.3]))
    # Xi = (-0.2, 2.3): a promoted (u >= 0.2), b robust (-u >= -2) -> u = 0.2, nothing relaxed
    assert s.on and s.relaxed == () and s.qp.relaxed == ()
    assert s.u[0] == pytest.approx(0.2, abs=1e-8)
    assert f.qp_solves == 1


def test_relaxed_problem_still_infeasible_raises_with_evidence():
    f = IntermittentSafetyFilter(Linear(1.0), c=1.0, b=0.3)
    # h = -0.5 each: robust rows u >= 0.5 and -u >= 0.5 cannot both hold
    with pytest.raises(InfeasibleFilterError) as info:
        f.step_lie(0.25, _lie([-0.5, -0.5], [[1.0], [-1.0]]), np.array([0.0]), x=np.array([1.0]))
    np.testing.assert_array_equal(info.value.barrier_values, [-0.5, -0.5])
    assert info.value.t == 0.25

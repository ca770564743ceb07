"""Audit additions: the relaxation policy, a QP accuracy regression, core-demo bad input."""

import numpy as np
import pytest

from isf_robot.cli import main
from isf_robot.core import (
    ConfigError,
    FilterQP,
    InfeasibleFilterError,
    IntermittentSafetyFilter,
    LieData,
    Linear,
    QPSolver,
    project_halfspace,
)
from isf_robot.demo_core import run_episode


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


# Found by hypothesis in test_qp_equals_closed_form_projection: ProxQP alone stopped 1.4e-5 away
# from the optimum on this nearly degenerate row while reporting success; QPSolver's active-set
# polish (checked against the KKT conditions) makes the answer exact.
def test_proxqp_matches_projection_on_a_nearly_degenerate_row():
    u_nom = np.array([0.0, 0.0, 0.00390625])
    a = np.array([0.5, 0.0, 0.001953125])
    res = QPSolver(closed_form=False).solve(FilterQP(u_nom, a[None, :], np.array([0.0])))
    np.testing.assert_allclose(res.u, project_halfspace(u_nom, a, 0.0), atol=1e-8, rtol=0)
    raw = QPSolver(closed_form=False, polish=False).solve(FilterQP(u_nom, a[None, :], np.array([0.0])))
    assert raw.status == "optimal"  # the unpolished answer is what the polish exists for


@pytest.mark.parametrize("seed", [-1, 1.5, True])
def test_core_demo_rejects_bad_seed(seed):
    with pytest.raises(ConfigError, match="seed must be a non-negative integer"):
        run_episode("isf", seed, duration=1.0)


@pytest.mark.parametrize("duration", [float("nan"), float("inf"), -1.0])
def test_core_demo_rejects_bad_duration(duration):
    with pytest.raises(ConfigError, match="duration"):
        run_episode("isf", 0, duration=duration)


@pytest.mark.parametrize(("argv", "needle"), [
    (["core-demo", "--duration", "nan"], "--duration"),
    (["core-demo", "--duration", "inf"], "--duration"),
    (["core-demo", "--seed", "-1"], "--seed"),
])
def test_core_demo_cli_bad_input_one_line(argv, needle, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err and "Traceback" not in err

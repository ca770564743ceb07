import numpy as np
import pytest

from isf_robot.core import (
    ConfigError,
    CustomClassK,
    DiscObstacleBarrier,
    IntermittentSafetyFilter,
    IsfError,
    Linear,
    NonFiniteError,
    Power,
    SafetyFilter,
    ShapeError,
    SingleIntegrator,
    UnknownNameError,
    as_class_k,
    miet_bound,
)


def make_isf(**kw):
    args = dict(alpha=Linear(1.0), c=0.5, b=0.5, system=SingleIntegrator(2), barriers=[DiscObstacleBarrier([1, 0], 0.3)])
    args.update(kw)
    return IntermittentSafetyFilter(**args)


def test_wrong_state_shape():
    f = make_isf()
    with pytest.raises(ShapeError, match=r"shape \(2,\)"):
        f.step(0.0, np.zeros(3), np.zeros(2))
    with pytest.raises(ShapeError):
        f.step(0.0, np.zeros((2, 1)), np.zeros(2))
    with pytest.raises(ShapeError, match="u_nom"):
        f.step(0.0, np.zeros(2), np.zeros(5))


def test_nan_state_and_command():
    f = make_isf()
    with pytest.raises(NonFiniteError, match="NaN"):
        f.step(0.0, np.array([np.nan, 0.0]), np.zeros(2))
    with pytest.raises(NonFiniteError):
        f.step(0.0, np.zeros(2), np.array([np.inf, 0.0]))
    with pytest.raises(NonFiniteError):
        f.step(float("nan"), np.zeros(2), np.zeros(2))


def test_non_class_k_alpha_rejected():
    with pytest.raises(ConfigError, match="alpha\\(0\\)"):
        CustomClassK(lambda h: h + 1.0)
    with pytest.raises(ConfigError, match="increasing"):
        CustomClassK(lambda h: -h)
    with pytest.raises(ConfigError, match="increasing"):
        as_class_k(lambda h: h**2)
    with pytest.raises(ConfigError):
        Linear(-1.0)
    with pytest.raises(ConfigError):
        Power(1.0, 0.0)
    with pytest.raises(ConfigError):
        make_isf(alpha="fast")
    assert as_class_k(lambda h: h**3 + h)(2.0) == 10.0


@pytest.mark.parametrize("c", [0.0, -1.0, float("nan")])
def test_c_must_be_positive(c):
    with pytest.raises(ConfigError, match="c"):
        make_isf(c=c)


def test_b_positive_and_d_bar_nonnegative():
    with pytest.raises(ConfigError, match="b"):
        make_isf(b=0.0)
    with pytest.raises(ConfigError, match="d_bar"):
        make_isf(d_bar=-0.1)
    with pytest.raises(ConfigError, match="d_bar"):
        SafetyFilter(Linear(1.0), d_bar=-1.0)
    with pytest.raises(ConfigError):
        miet_bound(1.0, 1.0, 1.0, d_bar=-1.0)


def test_bounds_validated():
    with pytest.raises(ConfigError, match="u_min must be <= u_max"):
        make_isf(u_min=[1.0, 1.0], u_max=[0.0, 2.0])
    with pytest.raises(ShapeError):
        make_isf(u_min=[0.0, 0.0, 0.0])
    with pytest.raises(ConfigError, match="on_infeasible"):
        make_isf(on_infeasible="ignore")


def test_unknown_name_lists_valid_and_everything_is_an_isf_error():
    err = UnknownNameError("scene", "pol", ["panda_pole", "planar"])
    assert "panda_pole, planar" in str(err)
    assert isinstance(err, IsfError) and isinstance(err, KeyError) and isinstance(err, ValueError)


def test_barrier_parameters_validated():
    with pytest.raises(ConfigError):
        DiscObstacleBarrier([0.0, 0.0], -1.0)
    with pytest.raises(NonFiniteError):
        DiscObstacleBarrier([0.0, np.nan], 1.0)


def test_nan_barrier_data_from_an_adapter_is_rejected():
    from isf_robot.core import LieData

    f = IntermittentSafetyFilter(Linear(1.0), c=0.5, b=0.5)
    bad = LieData(np.array([np.nan]), np.zeros(1), np.ones((1, 2)), np.ones(1), ("b",))
    with pytest.raises(NonFiniteError, match="h"):
        f.step_lie(0.0, bad, np.zeros(2))
    wrong = LieData(np.ones(2), np.zeros(2), np.ones((3, 2)), np.ones(2), ("a", "b"))
    with pytest.raises(ShapeError):
        f.step_lie(0.0, wrong, np.zeros(2))

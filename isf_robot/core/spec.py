"""The safety filters' parameters: one typed object, validated once.

:class:`FilterSpec` holds what the paper's filters are given (the class-K function ``alpha``, the
disturbance bound ``d_bar``, the intermittent filter's margin ``c`` and promotion rate ``b``) and the
intermittent filter's options (designed off periods, the predictive off trigger, the hand-over).
Everything else that names a filter parameter is derived from its fields: the filters take one
(:meth:`~isf_robot.core.filters.IntermittentSafetyFilter.from_spec`), a scene file's ``[filter]``
table is read into one (:meth:`FilterSpec.from_mapping`), the command lines' flags are made from
:data:`PARAMETERS`, and a run records :meth:`FilterSpec.as_info`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from .class_k import ClassK, Linear, as_class_k
from .exceptions import ConfigError

__all__ = ["FilterSpec", "Parameter", "PARAMETERS"]


@dataclass(frozen=True)
class Parameter:
    """What the command lines and scene files say of one :class:`FilterSpec` field.

    Attributes:
        name: The field (the scene file's ``[filter]`` key; the flag is ``--name`` with ``-`` for ``_``).
        help: One line for ``--help``.
        metavar: The flag's value name.
        intermittent: Only an intermittent strategy uses it.
        flag: The commands have a flag for it (``False``: scene files and scripts only).
        swept: ``isf-robot sweep`` can vary it (a flag of design choices; ``d_bar``, the disturbance the design
            must cover, is given once for every point).

    """

    name: str
    help: str
    metavar: str
    intermittent: bool
    flag: bool = True
    swept: bool = True


def _p(default: Any, help: str, metavar: str, intermittent: bool = True, flag: bool = True,  # noqa: A002
       swept: bool = True) -> Any:
    return field(default=default, metadata={"help": help, "metavar": metavar, "intermittent": intermittent,
                                            "flag": flag, "swept": flag and swept})


@dataclass(frozen=True)
class FilterSpec:
    """The parameters of a safety filter (every field is checked when the object is made).

    Attributes:
        alpha: Class-K function: a linear gain ``alpha(h) = alpha h`` [1/s], or a :class:`ClassK`.
        d_bar: Disturbance bound ``|d| <= d_bar`` of ``x_dot = f(x, u) + d``, >= 0 (an arm scene's 0:
            calibrate it).
        c: Off-trigger margin of the intermittent filter, > 0: off once every ``Xi_on >= c``.
        b: Promotion rate of the intermittent filter, > 0: ``Lf h - |dh/dx| d_bar >= b`` while on.
        min_off: Asked-for shortest off period [s] (0: the fixed margin ``c``); the margin is designed
            from the measured fall rate of ``Xi_on`` (:class:`~isf_robot.core.intermittent.FallRateBound`).
        c_max: Largest margin ``min_off`` may design (>= ``c``; ``inf``: none).
        fall_rate_prior: Fall rate of ``Xi_on`` assumed before the first measurement, >= 0.
        fall_rate_forget: Time constant [s] of the measured fall rate's memory, > 0.
        blend: Hand-over time [s] after each switch (0: the command steps at switches; ``None``: the
            adapter designs it, and the core filter alone takes 0). An arm scene's design:
            :func:`isf_robot.arm.filter_design.designed_options`.
        horizon: Horizon [s] of the predictive off trigger's rollout (0: none; the adapter rolls out;
            ``None``: the adapter designs it, as ``blend``).
        predict_every: Control steps between rollouts while the off condition holds, >= 1.
        c_pred: Off margin when the rollout predicts the nominal safe (0: none; ``0 < c_pred <= c``).
        shoot: Maneuvers by shooting: the horizon [s] of the rollout that scores each candidate promotion
            level (``b``, ``3 b``, ``10 b``) by the predicted re-trigger of the nominal after it
            (:mod:`isf_robot.core.shooting`; 0: always ``b``; the adapter rolls out).
        off_hold: The intermittent filter switches off only once its off condition has held this long [s]
            at every step (:class:`~isf_robot.core.triggers.OnOffTrigger`; ``None``: the adapter's default,
            0 for the core filter alone; 0: none).

    """

    alpha: float | ClassK = _p(5.0, "class-K gain [1/s]", "ALPHA", intermittent=False)
    d_bar: float = _p(0.0, "disturbance (tracking-error) bound", "D", intermittent=False, swept=False)
    c: float = _p(0.05, "off-trigger margin c", "C")
    b: float = _p(0.02, "promotion rate b", "B")
    min_off: float = _p(0.0, "asked-for shortest off period [s]: the off margin is designed from the measured "
                             "fall rate of Xi_on (at least c, at most c_max)", "S")
    c_max: float = _p(math.inf, "largest designed off margin", "C")
    fall_rate_prior: float = _p(0.0, "fall rate of Xi_on assumed before the first measurement", "R", flag=False)
    fall_rate_forget: float = _p(2.0, "time constant [s] of the measured fall rate's memory", "S", flag=False)
    blend: float | None = _p(None, "hand-over time [s] after each switch (no step in the command beyond what "
                                   "safety needs; 0: none; default: designed from the scene)", "S")
    horizon: float | None = _p(None, "predictive off trigger: off only if the nominal, rolled forward this long, "
                                     "keeps every Xi_on > 0 [s] (0: none; default: designed from the scene)", "S")
    predict_every: int = _p(5, "control steps between rollouts of the predictive off trigger", "K")
    c_pred: float = _p(0.0, "off margin when the rollout predicts the nominal safe over the horizon (0 < C <= c; "
                            "off as soon as it is predicted safe instead of at Xi_on >= c)", "C")
    shoot: float = _p(0.0, "maneuvers by shooting: while on, push with b, 3b or 10b, whichever the nominal, rolled "
                           "forward this long [s] after it, re-triggers latest on (0: always b)", "S")
    off_hold: float | None = _p(None, "switch off only once the off condition has held this long [s] (longer: "
                                      "fewer short off periods, more time on; default 0.1 for arms sharing a "
                                      "workspace, 0 for one arm; 0: none)", "S")

    def __post_init__(self) -> None:
        alpha = self.alpha
        if not isinstance(alpha, ClassK):
            _number(self, "alpha", positive=True)
        _number(self, "d_bar", nonneg=True)
        _number(self, "c", positive=True)
        _number(self, "b", positive=True)
        for name in ("min_off", "fall_rate_prior", "c_pred", "shoot"):
            _number(self, name, nonneg=True)
        for name in ("blend", "horizon", "off_hold"):
            if getattr(self, name) is not None:
                _number(self, name, nonneg=True)
        _number(self, "fall_rate_forget", positive=True, infinite=True)
        c_max = _number(self, "c_max", infinite=True)
        if not c_max >= self.c:
            raise ConfigError(f"filter parameter c_max must be >= c = {self.c}, got {c_max}")
        every = self.predict_every
        if isinstance(every, bool) or not isinstance(every, (int, float)) or int(every) != every or every < 1:
            raise ConfigError(f"filter parameter predict_every must be a whole number of control steps >= 1, "
                              f"got {every!r}")
        object.__setattr__(self, "predict_every", int(every))
        if self.c_pred > self.c:
            raise ConfigError(f"filter parameter c_pred must be <= c = {self.c}, got {self.c_pred}")

    @property
    def class_k(self) -> ClassK:
        """``alpha`` as a class-K function."""
        return as_class_k(self.alpha)

    def replace(self, **changes: Any) -> FilterSpec:
        """A copy with ``changes`` (checked again)."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], base: FilterSpec | None = None,
                     where: str = "filter parameters") -> FilterSpec:
        """``base`` (default: the defaults) with ``values`` (``None`` values ignored); unknown names are errors."""
        unknown = sorted(set(values) - set(NAMES))
        if unknown:
            raise ConfigError(f"{where}: unknown {', '.join(map(repr, unknown))}; valid: {', '.join(NAMES)}")
        given = {k: v for k, v in values.items() if v is not None}
        return (base or cls()).replace(**given) if given else (base or cls())

    def intermittent_kwargs(self) -> dict[str, Any]:
        """The intermittent filter's options (:class:`~isf_robot.core.filters.IntermittentSafetyFilter`)."""
        return {"min_off": self.min_off or None, "c_max": self.c_max, "fall_rate_prior": self.fall_rate_prior,
                "fall_rate_forget": self.fall_rate_forget, "predict_every": self.predict_every,
                "blend": self.blend or 0.0, "c_pred": self.c_pred or None, "shoot": self.shoot,
                "off_hold": self.off_hold or 0.0}

    def as_info(self, intermittent: bool = True) -> dict[str, Any]:
        """The parameters a run records: the four of the paper, and each intermittent option that is set.

        ``intermittent=False``: ``alpha`` and ``d_bar`` only. A non-linear class-K function is given by
        its description.
        """
        a = self.alpha
        out: dict[str, Any] = {"alpha": a.gain if isinstance(a, Linear) else a if isinstance(a, (int, float))
                               else str(a), "d_bar": self.d_bar}
        if not intermittent:
            return out
        out.update(c=self.c, b=self.b)
        default = _DEFAULTS
        if self.min_off:
            out.update(min_off=self.min_off, c_max=self.c_max)
        if self.blend:
            out["blend"] = self.blend
        if self.horizon:
            out.update(horizon=self.horizon, predict_every=self.predict_every)
        if self.c_pred:
            out["c_pred"] = self.c_pred
        if self.shoot:
            out["shoot"] = self.shoot
        if self.off_hold is not None:
            out["off_hold"] = self.off_hold
        for name in ("fall_rate_prior", "fall_rate_forget"):
            if getattr(self, name) != getattr(default, name):
                out[name] = getattr(self, name)
        return out


def _number(spec: FilterSpec, name: str, positive: bool = False, nonneg: bool = False,
            infinite: bool = False) -> float:
    v = getattr(spec, name)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ConfigError(f"filter parameter {name} must be a number, got {v!r}")
    v = float(v)
    if math.isnan(v) or (math.isinf(v) and not infinite):
        raise ConfigError(f"filter parameter {name} must be a finite number, got {v}")
    if positive and not v > 0:
        raise ConfigError(f"filter parameter {name} must be > 0, got {v}")
    if nonneg and not v >= 0:
        raise ConfigError(f"filter parameter {name} must be >= 0, got {v}")
    object.__setattr__(spec, name, v)
    return v


PARAMETERS: tuple[Parameter, ...] = tuple(
    Parameter(f.name, f.metadata["help"], f.metadata["metavar"], f.metadata["intermittent"], f.metadata["flag"],
              f.metadata["swept"])
    for f in dataclasses.fields(FilterSpec))
"""Every field of :class:`FilterSpec` with its help line, in order (the command lines' flags)."""

NAMES: tuple[str, ...] = tuple(p.name for p in PARAMETERS)
_DEFAULTS = FilterSpec()

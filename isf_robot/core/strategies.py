"""Strategies: the one place where ``"nominal"``, ``"cbf"`` and ``"isf"`` are defined.

A strategy turns a nominal command into the command to apply, given the barrier data of the
step (:class:`~isf_robot.core.system.LieData`). Every strategy has the interface of the core
filters: ``reset(t0)``, ``step_lie(t, lie, u_nom) -> FilterStep`` and the attribute
``uses_rows`` (whether it needs barrier rows at all; the nominal strategy does not, so an
adapter can skip building them).

The registry maps a name to a :class:`StrategyInfo` (summary line and factory). Adapters,
command lines and recorders ask the registry (:func:`strategy_names`, :func:`make_strategy`,
:func:`strategy_info`) and never compare strategy strings themselves; a new strategy is one
:func:`register_strategy` call.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from .exceptions import UnknownNameError
from .filters import FilterStep, IntermittentSafetyFilter, SafetyFilter
from .spec import FilterSpec
from .system import LieData

__all__ = [
    "Strategy",
    "StrategyInfo",
    "NominalStrategy",
    "register_strategy",
    "strategy_names",
    "strategy_info",
    "make_strategy",
    "INTERMITTENT_WIRING",
]

INTERMITTENT_WIRING = ("rollout", "shoot_rollout", "t0")
"""Keyword arguments only an intermittent strategy takes besides its :class:`FilterSpec` (the predictive
off trigger's rollout, the shooting rollout, the start time); :func:`make_strategy` drops them for the
other strategies."""


class Strategy(Protocol):
    """What a strategy offers an adapter (the core filters and :class:`NominalStrategy`)."""

    uses_rows: bool
    intermittent: bool

    @property
    def on(self) -> bool: ...

    def reset(self, t0: float = 0.0) -> None: ...

    def step_lie(self, t: float, lie: LieData, u_nom: np.ndarray, x: Any = None, **kw: Any) -> FilterStep: ...


class NominalStrategy:
    """No filter: the nominal command passes through; never "on", never a QP."""

    name = "nominal"
    uses_rows = False
    intermittent = False

    def reset(self, t0: float = 0.0) -> None:
        """Nothing to forget."""

    @property
    def on(self) -> bool:
        """Always off."""
        return False

    def step_lie(self, t: float, lie: LieData | None, u_nom: np.ndarray,
                 x: np.ndarray | None = None) -> FilterStep:
        """Return ``u_nom`` unchanged (``lie`` may be ``None``)."""
        if lie is None:
            return FilterStep._of(t, u_nom, u_nom, False, _EMPTY, _EMPTY)
        return FilterStep._of(t, u_nom, u_nom, False, lie.h, np.full(lie.h.shape, np.inf), names=lie.names)


_EMPTY = np.zeros(0)
_EMPTY.flags.writeable = False  # shared by every step without rows


@dataclass(frozen=True)
class StrategyInfo:
    """A registered strategy.

    Attributes:
        name: Its name on the command line and in results.
        summary: One line for ``--help``.
        factory: ``factory(spec, **wiring) -> strategy``.
        intermittent: Whether it is an on/off (event-triggered) filter with the margin ``c``.
        filters: Whether it ever changes the nominal command.

    """

    name: str
    summary: str
    factory: Callable[..., Any]
    intermittent: bool = False
    filters: bool = True


_REGISTRY: dict[str, StrategyInfo] = {}


def register_strategy(info: StrategyInfo) -> None:
    """Add (or replace) a strategy in the registry."""
    _REGISTRY[info.name] = info


def strategy_names() -> tuple[str, ...]:
    """Registered strategy names, in registration order."""
    return tuple(_REGISTRY)


def strategy_info(name: str) -> StrategyInfo:
    """The registered strategy ``name``.

    Raises:
        UnknownNameError: ``name`` is not registered (the message lists the valid names).

    """
    try:
        return _REGISTRY[name]
    except KeyError:
        raise UnknownNameError("strategy", name, tuple(_REGISTRY)) from None


def make_strategy(name: str, spec: FilterSpec, **wiring: Any) -> Strategy:
    """Build the strategy ``name`` with the filter parameters ``spec`` (those it does not use are ignored).

    Args:
        name: A registered strategy name.
        spec: The filter parameters.
        **wiring: Passed to the filter (system, barriers, solver, bounds, infeasibility policy, screening,
            ...); :data:`INTERMITTENT_WIRING` only to intermittent strategies.

    """
    info = strategy_info(name)
    if not info.intermittent:
        wiring = {k: v for k, v in wiring.items() if k not in INTERMITTENT_WIRING}
    return info.factory(spec, **wiring)  # type: ignore[no-any-return]


register_strategy(StrategyInfo(
    "nominal", "no filter: the nominal command as it is (shows the danger)",
    lambda spec, **_: NominalStrategy(), intermittent=False, filters=False))
register_strategy(StrategyInfo(
    "cbf", "the standard robust safety filter, solved every control step", SafetyFilter.from_spec))
register_strategy(StrategyInfo(
    "isf", "the intermittent safety filter: on at Xi_on <= 0, promotes, off at Xi_on >= c",
    IntermittentSafetyFilter.from_spec, intermittent=True))

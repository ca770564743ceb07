"""The result of one filter step (:class:`FilterStep`), shared by every strategy."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .qp import QPResult
from .switches import SwitchEvent

__all__ = ["FilterStep"]

_new, _set = object.__new__, object.__setattr__  # (FilterStep._of: a frozen dataclass's __dict__ set whole)


@dataclass(frozen=True)
class FilterStep:
    """One control step of a filter.

    Attributes:
        t: Time [s].
        u: The command to apply, shape (m,). When the filter passes the nominal command through
            (``u == u_nom``), this is the caller's ``u_nom`` array itself, not a copy: copy it
            to keep it past a later change of that array (a nominal controller may reuse its
            output buffer).
        u_nom: The nominal command, shape (m,) (the caller's float array itself when given one).
        on: Whether the filter acted in this step (intermittent: its mode; standard: a
            constraint was active).
        h: Barrier values, shape (k,).
        xi: ``Xi_on`` per barrier under the nominal command, shape (k,).
        event: The on/off switch at this step, if any.
        qp: The QP result when a QP was solved, else ``None``.
        relaxed: Names of barriers whose promotion was relaxed in this step.
        fallback: Whether the command came from the infeasibility fallback.
        names: Barrier labels.
        resolved: Whether a screened row was needed, so the QP was solved again with every row.
        margin: The off margin in force at this step (intermittent filter: ``c``, or the margin
            designed for ``min_off``; ``None`` for other strategies).
        off_bound_s: At an off switch, the shortest off period the margin guarantees at the
            measured fall rate of ``Xi_on`` (:class:`~isf_robot.core.intermittent.FallRateBound`).
        rollout: Whether the predictive off trigger ran a rollout in this step.
        held: Whether the prediction kept the filter on although every ``Xi_on >= margin``.

    """

    t: float
    u: np.ndarray
    u_nom: np.ndarray
    on: bool
    h: np.ndarray
    xi: np.ndarray
    event: SwitchEvent | None = None
    qp: QPResult | None = None
    relaxed: tuple[str, ...] = ()
    fallback: bool = False
    names: tuple[str, ...] = field(default_factory=tuple)
    resolved: bool = False
    margin: float | None = None
    off_bound_s: float | None = None
    rollout: bool = False
    held: bool = False

    @classmethod
    def _of(cls, t: float, u: np.ndarray, u_nom: np.ndarray, on: bool, h: np.ndarray, xi: np.ndarray,
            event: SwitchEvent | None = None, qp: QPResult | None = None, relaxed: tuple[str, ...] = (),
            fallback: bool = False, names: tuple[str, ...] = (), resolved: bool = False,
            margin: float | None = None, off_bound_s: float | None = None, rollout: bool = False,
            held: bool = False) -> FilterStep:
        """The step with these fields: the filters' fast path.

        Same object as ``FilterStep(...)`` would build, without the frozen dataclass's
        field-by-field ``__init__`` (about 6 us per call against 1 us): its ``__dict__`` is set
        whole.
        """
        step = _new(cls)
        _set(step, "__dict__", {"t": t, "u": u, "u_nom": u_nom, "on": on, "h": h, "xi": xi, "event": event, "qp": qp,
                                "relaxed": relaxed, "fallback": fallback, "names": names, "resolved": resolved,
                                "margin": margin, "off_bound_s": off_bound_s, "rollout": rollout, "held": held})
        return step

    @property
    def h_min(self) -> float:
        """Smallest barrier value."""
        return float(self.h.min()) if self.h.size else float("inf")

    @property
    def xi_min(self) -> float:
        """Smallest ``Xi_on``."""
        return float(self.xi.min()) if self.xi.size else float("inf")

    @property
    def solved_qp(self) -> bool:
        """Whether a QP (or its closed form) was solved in this step."""
        return self.qp is not None

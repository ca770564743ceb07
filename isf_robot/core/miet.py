"""Minimum inter-event time (paper, Proposition 1) and a Zeno guard.

``tau = c / (L_Xi (B + d_bar))`` with ``B >= |F(x)|`` on the safe set and ``L_Xi`` a Lipschitz
constant of the trigger function ``Xi``. The constants may be given or estimated by sampling;
a sampled estimate is not a proof, so always report the measured minimum inter-event time
beside the bound.

The proposition's argument bounds ``|dXi/dt| = |dXi/dx (F(x) + d)|`` by ``L_Xi (B + d_bar)``:
after a jump ``Xi >= c``, so ``Xi`` cannot reach 0 sooner than ``c / sup |dXi/dt|``. Taking the
two suprema apart multiplies the largest gradient (found where the state is slow) by the largest
flow (found elsewhere), which can make the bound vacuous. :func:`estimate_miet_rate` takes the
same argument with the rate bounded state by state, ``|dXi/dx F(x)| + |dXi/dx_d| d_bar`` (``x_d``
the coordinates the disturbance enters), whose supremum is never larger: the same proposition,
a bound at least as long.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from .exceptions import ConfigError, ZenoError
from .sums import dot, norm
from .validation import check_nonnegative, check_positive

__all__ = [
    "miet_bound", "MietConstants", "estimate_miet_constants", "MietRate", "estimate_miet_rate", "ZenoGuard",
    "min_interval",
]


def miet_bound(c: float, lipschitz_xi: float, flow_bound: float, d_bar: float = 0.0) -> float:
    """Return ``c / (L_Xi (B + d_bar))`` [s].

    Args:
        c: Post-jump / off-trigger margin, > 0.
        lipschitz_xi: ``L_Xi`` > 0.
        flow_bound: ``B`` >= 0.
        d_bar: Disturbance bound >= 0.

    """
    c = check_positive(c, "c")
    L = check_positive(lipschitz_xi, "L_Xi (Lipschitz constant of Xi)")
    B = check_nonnegative(flow_bound, "B (flow bound)")
    d = check_nonnegative(d_bar, "d_bar")
    if B + d == 0.0:
        return float("inf")
    return c / (L * (B + d))


@dataclass(frozen=True)
class MietConstants:
    """Sampled constants and the bound they give.

    Attributes:
        lipschitz_xi: Largest sampled ``|dXi/dx|``.
        flow_bound: Largest sampled ``|F(x)|``.
        bound_s: ``c / (L_Xi (B + d_bar))`` [s].
        samples: Number of samples used.

    """

    lipschitz_xi: float
    flow_bound: float
    bound_s: float
    samples: int


def estimate_miet_constants(
    xi: Callable[[np.ndarray], float],
    flow: Callable[[np.ndarray], np.ndarray],
    samples: Iterable[np.ndarray],
    c: float,
    d_bar: float = 0.0,
    eps: float = 1e-6,
) -> MietConstants:
    """Estimate ``L_Xi`` and ``B`` by sampling states of the safe set.

    ``|dXi/dx|`` is computed by central differences with relative step ``eps``.
    """
    L = 0.0
    B = 0.0
    count = 0
    for x in samples:
        x = np.asarray(x, dtype=float)
        grad = _gradient(xi, x, eps)
        L = max(L, norm(grad))
        B = max(B, norm(np.asarray(flow(x), dtype=float)))
        count += 1
    if count == 0:
        raise ConfigError("estimate_miet_constants needs at least one sample")
    if L == 0.0:
        return MietConstants(0.0, B, float("inf"), count)
    return MietConstants(L, B, miet_bound(c, L, B, d_bar), count)


def _gradient(xi: Callable[[np.ndarray], float], x: np.ndarray, eps: float) -> np.ndarray:
    """``dXi/dx`` at ``x`` by central differences, relative step ``eps``."""
    grad = np.empty_like(x)
    for i in range(x.shape[0]):
        step = eps * max(1.0, abs(x[i]))
        xp = x.copy()
        xm = x.copy()
        xp[i] += step
        xm[i] -= step
        grad[i] = (xi(xp) - xi(xm)) / (2 * step)
    return grad


@dataclass(frozen=True)
class MietRate:
    """A sampled bound on ``|dXi/dt|`` and the inter-event time it gives.

    Attributes:
        rate_bound: Largest sampled ``|dXi/dx F(x)| + |dXi/dx_d| d_bar`` [Xi units / s].
        bound_s: ``c / rate_bound`` [s] (``inf`` when the rate is 0).
        samples: Number of samples used.

    """

    rate_bound: float
    bound_s: float
    samples: int


def estimate_miet_rate(
    xi: Callable[[np.ndarray], float],
    flow: Callable[[np.ndarray], np.ndarray],
    samples: Iterable[np.ndarray],
    c: float,
    d_bar: float = 0.0,
    disturbed: Sequence[int] | None = None,
    eps: float = 1e-6,
) -> MietRate:
    """Inter-event time ``c / sup |dXi/dt|`` with the rate bounded state by state (see the module docstring).

    Args:
        xi: Trigger function ``Xi(x)``.
        flow: Model flow ``F(x)``.
        samples: States of the set the trajectory stays in between jumps.
        c: Post-jump margin, > 0 (``Xi(x+) >= c``).
        d_bar: Bound on the disturbance ``|d|``, >= 0.
        disturbed: Indices of the state the disturbance enters (default: all).
        eps: Relative step of the central differences of ``dXi/dx``.

    Raises:
        ConfigError: No samples, ``c <= 0`` or ``d_bar < 0``.

    """
    c = check_positive(c, "c")
    d = check_nonnegative(d_bar, "d_bar")
    rate = 0.0
    count = 0
    for x in samples:
        x = np.asarray(x, dtype=float)
        grad = _gradient(xi, x, eps)
        gd = grad if disturbed is None else grad[list(disturbed)]
        rate = max(rate, abs(dot(grad, np.asarray(flow(x), dtype=float))) + norm(gd) * d)
        count += 1
    if count == 0:
        raise ConfigError("estimate_miet_rate needs at least one sample")
    return MietRate(rate, c / rate if rate > 0.0 else float("inf"), count)


def min_interval(times: Iterable[float]) -> float | None:
    """Smallest difference between consecutive event times, or ``None`` for fewer than two."""
    t = np.asarray(list(times), dtype=float)
    if t.size < 2:
        return None
    return float(np.min(np.diff(t)))


class ZenoGuard:
    """Stop a run when events accumulate.

    Fires when ``window`` consecutive events all fall within ``min_span`` seconds
    (default: 20 events in under 1e-6 s), or when a single interval is shorter than
    ``min_interval`` (default 0: disabled).

    Args:
        window: Number of events considered, >= 2.
        min_span: Shortest allowed time span of ``window`` events [s], >= 0.
        min_interval: Shortest allowed single interval [s], >= 0.

    """

    def __init__(self, window: int = 20, min_span: float = 1e-6, min_interval: float = 0.0) -> None:
        if int(window) < 2:
            raise ConfigError(f"window must be >= 2, got {window}")
        self.window = int(window)
        self.min_span = check_nonnegative(min_span, "min_span")
        self.min_interval = check_nonnegative(min_interval, "min_interval")
        self.reset()

    def reset(self) -> None:
        """Forget recorded events."""
        self._times: deque[float] = deque(maxlen=self.window)
        self._intervals: deque[float] = deque(maxlen=self.window)

    def record(self, t: float, interval: float | None = None) -> None:
        """Record an event at ``t``; raise :class:`ZenoError` when the guard fires."""
        if interval is None and self._times:
            interval = t - self._times[-1]
        self._times.append(t)
        if interval is not None:
            self._intervals.append(interval)
            if len(self._times) > 1 and interval < self.min_interval:
                raise ZenoError(
                    f"Zeno guard: inter-event time {interval:.3g} s at t={t:.6g} s is below the "
                    f"allowed minimum {self.min_interval:.3g} s",
                    t=t, intervals=list(self._intervals),
                )
        if len(self._times) == self.window and self._times[-1] - self._times[0] < self.min_span:
            raise ZenoError(
                f"Zeno guard: {self.window} events within {self._times[-1] - self._times[0]:.3g} s "
                f"(limit {self.min_span:.3g} s) at t={t:.6g} s",
                t=t, intervals=list(self._intervals),
            )

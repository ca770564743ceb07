"""Wall time per phase of the arm loop, as wrappers: the loop itself has no timers."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

__all__ = ["PhaseTimers"]


class PhaseTimers:
    """Replaces each phase callable by one that adds its wall time to ``totals``."""

    def __init__(self, phases: dict[str, Callable[..., Any]]) -> None:
        self.totals: dict[str, float] = dict.fromkeys(phases, 0.0)
        for name, fn in phases.items():
            phases[name] = self._timed(name, fn)

    def _timed(self, name: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        perf, totals = time.perf_counter, self.totals

        def timed(*args: Any) -> Any:
            t0 = perf()
            out = fn(*args)
            totals[name] += perf() - t0
            return out

        return timed

"""MetricsAccumulator.add_step's batched figures (intervention, jumps): the step-by-step figures, bit for bit.

The reference below is add_step as it was, computing ``|u - u_nom|^2`` and ``|u_k - u_{k-1}|^2`` in
every step; the accumulator now makes them per batch of steps. Every array, the metrics and the
solver figures must be the same floats, with switch events, ``u is u_nom``, NaN, commands of another
type, steps added with ``add()`` in between, reads in the middle and packing.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from isf_robot.core import MetricsAccumulator, metrics
from isf_robot.core.step import FilterStep
from isf_robot.core.switches import SwitchEvent


def _sq(d) -> float:  # type: ignore[no-untyped-def]
    """|d|^2 as the metrics define it: the squares added in index order from 0 (sums.sq_sum), in plain floats."""
    s = 0.0
    for x in d.tolist():
        s += x * x
    return s


class _Reference:
    """add_step's figures step by step (the accumulator before batching)."""

    def __init__(self) -> None:
        self.rates: list[float] = []
        self.u_prev = None
        self.jump2 = self.switch_jump2 = None

    def add(self, u, u_nom) -> None:  # type: ignore[no-untyped-def]
        self.rates.append(_sq(u - u_nom))

    def add_step(self, step) -> None:  # type: ignore[no-untyped-def]
        u, u_nom = step.u, step.u_nom
        if type(u) is not np.ndarray or u.dtype != np.float64:
            u = np.asarray(u, dtype=float)
        if u is u_nom:
            rate = 0.0
        else:
            rate = _sq(u - u_nom)
        self.rates.append(rate)
        prev, self.u_prev = self.u_prev, u.copy()
        if prev is not None:
            j = _sq(u - prev)
            if self.jump2 is None or j > self.jump2:
                self.jump2 = j
            if step.event is not None and (self.switch_jump2 is None or j > self.switch_jump2):
                self.switch_jump2 = j


def _steps(rng: np.random.Generator, n: int):  # type: ignore[no-untyped-def]
    m = 3
    buf = np.zeros(m)
    for k in range(n):
        u_nom = rng.normal(size=m) * 10.0 ** rng.uniform(-3, 3)
        r = rng.random()
        if r < 0.4:
            u = u_nom  # (passed through: the same object)
        elif r < 0.45:
            buf[:] = rng.normal(size=m)  # (a nominal that reuses its output buffer)
            u = u_nom = buf
        elif r < 0.5:
            u = list(rng.normal(size=m))  # (not an array)
        elif r < 0.53:
            u, u_nom = rng.normal(size=m), u_nom.astype(np.float32)
        elif r < 0.54:
            u = np.full(m, math.nan)
        else:
            u = u_nom + rng.normal(size=m) * 10.0 ** rng.uniform(-6, 1)
        ev = SwitchEvent(k * 1e-3, "on", 0.0, 1) if rng.random() < 0.05 else None
        yield k, FilterStep._of(k * 1e-3, u, u_nom, bool(r > 0.4), np.zeros(1), np.zeros(1), ev)


@pytest.mark.parametrize("batch, chunk", [(metrics._BATCH, metrics._CHUNK), (5, 1 << 16), (7, 11), (1, 3)])
def test_batched_figures_are_the_step_by_step_figures(batch, chunk, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(metrics, "_BATCH", batch)
    monkeypatch.setattr(metrics, "_CHUNK", chunk)
    rng = np.random.default_rng(batch)
    acc, ref = MetricsAccumulator(), _Reference()
    for k, step in _steps(rng, 1500):
        if k % 97 == 5:  # a step recorded with add() in between
            u, un = rng.normal(size=2), rng.normal(size=2)
            acc.add(k * 1e-3, 1e-3, False, u, un, False)
            ref.add(u, un)
        acc.add_step(step, 1e-3)
        ref.add_step(step)
        if k % 331 == 0 or k in (255, 256, 257):  # reads in the middle make the batch's figures so far
            st = acc.stats()
            assert (repr(st.jump_max), repr(st.switch_jump_max)) == (
                repr(None if ref.jump2 is None else math.sqrt(ref.jump2)),
                repr(None if ref.switch_jump2 is None else math.sqrt(ref.switch_jump2)))
            assert acc.arrays()["intervention_rate"].tobytes() == np.array(ref.rates).tobytes()
        if isinstance(step.u, np.ndarray) and step.u is step.u_nom and step.u.base is None and k % 2:
            step.u[:] = 99.0  # (the caller reuses its buffer after the step: the batch kept the values)
    st = acc.stats()
    assert repr(st.jump_max) == repr(math.sqrt(ref.jump2)) and repr(st.switch_jump_max) == repr(math.sqrt(ref.switch_jump2))
    a = acc.arrays()
    assert a["intervention_rate"].tobytes() == np.array(ref.rates).tobytes() and len(acc) == len(ref.rates)
    assert np.isnan(a["intervention_rate"]).any() and (a["intervention_rate"] == 0.0).any()
    assert repr(acc.result().intervention) == repr(float(np.sum(np.array(ref.rates) * a["dt"])))

"""Shooting controller (issue 14, item 5): the impulse that maximises the predicted time to the next trigger.

The paper's controller (:class:`satellite.control.controller.SafeguardingController`) aims at a Kepler
orbit; with Itokawa's non-Kepler pull (18-27 % of the point mass) the orbit it reaches in the
truth field does not depend on where it fired, and the time to the next trigger is flat in ``h``.
This controller chooses the impulse by short-horizon shooting in the run's truth field instead:

1. **Candidates** (all in the current orbital plane, sense of motion kept, like the paper's):
   the paper's own impulse, and post-jump velocities ``v+ = v_c (f_t t_hat + f_r r_hat)`` on a
   ``grid x grid`` lattice ``f_t in 1 + span [-1, 1]``, ``f_r in span [-1, 1]``, with
   ``v_c = sqrt(mu / r)`` the circular speed at the current radius. Each grid point is a conic
   through the current position (the paper's family of a target apsis and a placement is a
   curve through this lattice); ``f_t = 1, f_r = 0`` is the Kepler circular orbit.
2. **Post-jump conditions**: a candidate is kept only if ``Xi(G(x, v)) >= c`` (the core's
   formula through :class:`satellite.control.triggers.BandTriggers`, eq. control_jump_cond; ``h`` is
   unchanged by an impulse) and ``|v+ - v| <= dv_max`` when a limit is set.
3. **Prediction**: each kept candidate is propagated in the truth field
   (:meth:`satellite.orbit.model.OrbitModel.truth_rhs`, spinning body, from the current time) by
   classical fourth-order Runge-Kutta with a fixed step ``step_s`` until ``Xi <= 0`` (the greedy
   trigger, eq. trigger:greedy; the crossing is interpolated linearly between steps) or until
   ``horizon_h`` (the prediction is then the horizon).
4. **Choice**: the largest predicted time; ties (several candidates reach the horizon) go to the
   smaller ``|dv|``, counted in steps of ``1e-12 v_c`` (far below any thruster's resolution, far
   above the ~1e-16 ``v_c`` rounding of ``v+ - v``: two impulses that are both none, e.g. the paper's
   and the lattice's circular orbit at the band's centre, tie on every machine instead of being
   ranked by their rounding noise), then to the earlier candidate (the paper's is the first). Then
   ``refine`` rounds of the 8 lattice neighbours of the best grid point at a third of the previous
   spacing.

Bounded cost per impulse: at most ``grid^2 + 1 + 8 refine`` predictions of at most
``ceil(horizon / step)`` steps of 4 truth evaluations (defaults 7, 24 h, 120 s, 1 round:
58 x 720 x 4 = 167,040 evaluations; most candidates trigger within a few hours and a candidate
that cannot beat a horizon-reaching one on ``|dv|`` is not propagated, so typical impulses take
2-20 thousand evaluations). Deterministic: no randomness, a pure function of ``(t, x)`` and the model.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from isf_robot.core.sums import norm
from satellite.control.triggers import BandTriggers
from satellite.errors import SatelliteError
from satellite.orbit.model import OrbitModel

__all__ = [
    "ShootingParams", "ShootingError", "ShotPlan", "ShootingController", "plane_basis", "predict_trigger",
    "shooting_report",
]


class ShootingError(SatelliteError):
    """No candidate impulse meets the post-jump conditions within the delta-v limit."""


@dataclass(frozen=True)
class ShootingParams:
    """Settings of the shooting controller.

    Attributes:
        horizon_h: Prediction horizon [h], > 0 (the prediction is capped there).
        step_s: Runge-Kutta step of the prediction [s], > 0 and <= 600.
        grid: Lattice points per axis, odd, >= 3 (so the circular orbit is a candidate).
        span: Half-width of the lattice as a fraction of the circular speed, in (0, 0.5].
        refine: Refinement rounds around the best lattice point, >= 0.
        dv_max: Largest impulse [m/s] (``None``: no limit beyond the lattice).

    """

    horizon_h: float = 24.0
    step_s: float = 120.0
    grid: int = 7
    span: float = 0.15
    refine: int = 1
    dv_max: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.horizon_h) and self.horizon_h > 0.0):
            raise SatelliteError(f"shooting horizon must be a positive number of hours, got {self.horizon_h}")
        if not (math.isfinite(self.step_s) and 0.0 < self.step_s <= 600.0):
            raise SatelliteError(f"shooting step must be in (0, 600] seconds, got {self.step_s}")
        if isinstance(self.grid, bool) or not isinstance(self.grid, int) or self.grid < 3 or self.grid % 2 == 0:
            raise SatelliteError(f"shooting grid must be an odd integer >= 3, got {self.grid!r}")
        if not (math.isfinite(self.span) and 0.0 < self.span <= 0.5):
            raise SatelliteError(f"shooting span must be in (0, 0.5] (fraction of the circular speed), got {self.span}")
        if isinstance(self.refine, bool) or not isinstance(self.refine, int) or self.refine < 0:
            raise SatelliteError(f"shooting refine must be an integer >= 0, got {self.refine!r}")
        if self.dv_max is not None and not (math.isfinite(self.dv_max) and self.dv_max > 0.0):
            raise SatelliteError(f"shooting dv_max must be a positive speed [m/s], got {self.dv_max}")

    @property
    def max_predictions(self) -> int:
        """Most predictions per impulse."""
        return self.grid * self.grid + 1 + 8 * self.refine

    @property
    def max_rhs_evaluations(self) -> int:
        """Most truth evaluations per impulse (the cost bound)."""
        return self.max_predictions * math.ceil(self.horizon_h * 3600.0 / self.step_s) * 4

    def describe(self) -> dict[str, float | int | None]:
        """JSON-ready settings."""
        return {"horizon_h": self.horizon_h, "step_s": self.step_s, "grid": self.grid, "span": self.span,
                "refine": self.refine, "dv_max": self.dv_max, "max_rhs_evaluations": self.max_rhs_evaluations}


@dataclass(frozen=True)
class ShotPlan:
    """One chosen impulse.

    Attributes:
        t: Time [s].
        dv: Impulse [m/s], shape (3,).
        predicted_s: Predicted time to the next trigger [s] (capped at the horizon).
        paper_predicted_s: The paper's impulse's predicted time [s] (``nan`` when it was not kept).
        chosen: ``"paper"`` or ``"lattice"``.
        candidates: Candidates considered; ``kept``: those meeting the conditions; ``propagated``:
            those predicted; ``rhs_evals``: truth evaluations spent.

    """

    t: float
    dv: NDArray[np.float64]
    predicted_s: float
    paper_predicted_s: float
    chosen: str
    candidates: int
    kept: int
    propagated: int
    rhs_evals: int


def plane_basis(x: NDArray[np.float64]) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """``(r, r_hat, t_hat)`` of the current orbital plane, ``t_hat = k_hat x r_hat`` (sense of motion kept).

    When the velocity is (almost) radial the plane is undefined; the plane through ``r`` and the
    z axis (or the x axis when ``r`` is along z) is used.
    """
    rv = np.asarray(x[:3], dtype=float)
    vv = np.asarray(x[3:6], dtype=float)
    r = norm(rv)
    if not (math.isfinite(r) and r > 0.0):
        raise SatelliteError(f"controller needs a finite non-zero position, got {rv}")
    rhat = rv / r
    k = np.cross(rv, vv)
    kn = norm(k)
    if not kn > 1e-9 * r * max(norm(vv), 1e-300):
        axis = np.array([0.0, 0.0, 1.0]) if abs(rhat[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        k = np.cross(rhat, axis)
        kn = norm(k)
    return r, rhat, np.cross(k / kn, rhat)


def predict_trigger(
    rhs: Callable[[float, NDArray[np.float64]], NDArray[np.float64]],
    xi: Callable[[float, NDArray[np.float64]], float],
    t0: float,
    x0: NDArray[np.float64],
    horizon_s: float,
    step_s: float,
) -> tuple[float, int]:
    """Time [s] from ``(t0, x0)`` to the first ``xi <= 0`` along ``rhs`` (RK4, fixed step), capped at ``horizon_s``.

    The crossing is interpolated linearly between the two steps around it. Returns the time and
    the number of ``rhs`` evaluations.
    """
    t, y = t0, np.array(x0, dtype=float)
    g0 = xi(t, y)
    if g0 <= 0.0:
        return 0.0, 0
    h, h2, h6 = step_s, 0.5 * step_s, step_s / 6.0
    n = math.ceil(horizon_s / step_s)
    for i in range(n):
        k1 = rhs(t, y)
        k2 = rhs(t + h2, y + h2 * k1)
        k3 = rhs(t + h2, y + h2 * k2)
        k4 = rhs(t + h, y + h * k3)
        y = y + h6 * (k1 + 2.0 * (k2 + k3) + k4)
        g1 = xi(t + h, y)
        if g1 <= 0.0:
            return min(t - t0 + h * g0 / (g0 - g1), horizon_s), 4 * (i + 1)
        t, g0 = t + h, g1
    return horizon_s, 4 * n


class ShootingController:
    """The shooting safeguarding controller ``K(t, x)`` (see the module docstring).

    Args:
        model: The run's model (truth field with the run's body phase; supplies mu).
        trig: Band trigger values (``Xi`` of the prediction and of the post-jump check).
        c: Post-jump margin [m^2/s].
        params: Shooting settings.
        paper: The paper's controller ``K(t, x) -> dv`` (always a candidate).

    Attributes:
        plans: Every chosen impulse (:class:`ShotPlan`), in order.

    """

    def __init__(
        self,
        model: OrbitModel,
        trig: BandTriggers,
        c: float,
        params: ShootingParams,
        paper: Callable[[float, NDArray[np.float64]], NDArray[np.float64]],
    ) -> None:
        self.model = model
        self.trig = trig
        self.c = float(c)
        self.params = params
        self.paper = paper
        self.horizon_s = params.horizon_h * 3600.0
        self.plans: list[ShotPlan] = []

    def plan(self, t: float, x: NDArray[np.float64]) -> ShotPlan:
        """Choose the impulse at ``(t, x)``.

        Raises:
            ShootingError: No candidate meets ``Xi(G(x, v)) >= c`` within ``dv_max``.

        """
        p = self.params
        x = np.asarray(x, dtype=float)
        r, rhat, that = plane_basis(x)
        vc = math.sqrt(self.model.mu / r)
        v = x[3:6]
        self._best: tuple[float, float, int] | None = None  # (predicted, -|dv| in steps of dv_step, -order)
        self._dv_step = 1e-12 * vc  # |dv| resolution of the tie-break (module docstring, 4.)
        self._best_dv: NDArray[np.float64] | None = None
        self._best_f: tuple[float, float] | None = None
        self._counts = [0, 0, 0, 0]  # candidates, kept, propagated, rhs evaluations
        paper_dv = np.asarray(self.paper(t, x), dtype=float)
        paper_pred = self._consider(t, x, paper_dv, None)
        offsets = p.span * np.linspace(-1.0, 1.0, p.grid)
        for fr in offsets.tolist():
            for ft in offsets.tolist():
                self._consider(t, x, vc * ((1.0 + ft) * that + fr * rhat) - v, (ft, fr))
        spacing = p.span * 2.0 / (p.grid - 1)
        for _ in range(p.refine):
            if self._best_f is None:
                break
            spacing /= 3.0
            ft0, fr0 = self._best_f
            for dr in (-spacing, 0.0, spacing):
                for dt in (-spacing, 0.0, spacing):
                    if dr != 0.0 or dt != 0.0:
                        ft, fr = ft0 + dt, fr0 + dr
                        self._consider(t, x, vc * ((1.0 + ft) * that + fr * rhat) - v, (ft, fr))
        if self._best is None or self._best_dv is None:
            lim = f" within dv_max = {p.dv_max:g} m/s" if p.dv_max is not None else ""
            raise ShootingError(
                f"no candidate impulse at t = {t:.6g} s, r = {r / self.model.R:.4f} R gives Xi(G(x, v)) >= c = "
                f"{self.c:.4g}{lim} (the paper's impulse included); raise the limit (--shoot-dv-max) or lower c"
            )
        n_cand, n_kept, n_prop, n_rhs = self._counts
        plan = ShotPlan(t, self._best_dv, self._best[0], paper_pred, "paper" if self._best_f is None else "lattice",
                        n_cand, n_kept, n_prop, n_rhs)
        self.plans.append(plan)
        return plan

    def _consider(self, t: float, x: NDArray[np.float64], dv: NDArray[np.float64],
                  f: tuple[float, float] | None) -> float:
        """Check, predict and rank one candidate; return its prediction (``nan`` when not kept)."""
        self._counts[0] += 1
        mag = float(np.linalg.norm(dv))
        if not np.all(np.isfinite(dv)) or (self.params.dv_max is not None and mag > self.params.dv_max):
            return math.nan
        y = np.array(x, dtype=float)
        y[3:6] += dv
        if not self.trig.xi(t, y) >= self.c:
            return math.nan
        self._counts[1] += 1
        best = self._best
        dv_key = -float(np.rint(mag / self._dv_step))  # (a float: no overflow for a huge impulse)
        if best is not None and best[0] >= self.horizon_s and dv_key <= best[1]:
            return math.nan  # cannot beat a horizon-reaching candidate: same time at best, not less dv
        pred, evals = predict_trigger(self.model.truth_rhs, self.trig.xi, t, y, self.horizon_s, self.params.step_s)
        self._counts[2] += 1
        self._counts[3] += evals
        key = (pred, dv_key, -self._counts[0])
        if best is None or key > best:
            self._best, self._best_dv, self._best_f = key, dv, f
        return pred

    def __call__(self, t: float, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Impulse ``dv`` [m/s], shape (3,)."""
        return self.plan(t, x).dv


def shooting_report(controller: object) -> dict[str, float | int | None] | None:
    """What a run's shooting controller did (``None`` for any other controller).

    Keys: ``shooting_impulses``, ``shooting_paper_chosen`` (impulses where the paper's impulse
    won), ``shooting_predicted_median_h`` and ``shooting_paper_predicted_median_h`` (median
    predicted time to the next trigger of the chosen and of the paper's impulse), and
    ``shooting_rhs_evals_mean``/``_max`` (truth evaluations per impulse).
    """
    if not isinstance(controller, ShootingController):
        return None
    plans = controller.plans
    if not plans:
        return {"shooting_impulses": 0, "shooting_paper_chosen": 0, "shooting_predicted_median_h": None,
                "shooting_paper_predicted_median_h": None, "shooting_rhs_evals_mean": None,
                "shooting_rhs_evals_max": None}
    pred = np.array([p.predicted_s for p in plans]) / 3600.0
    paper = np.array([p.paper_predicted_s for p in plans]) / 3600.0
    evals = np.array([p.rhs_evals for p in plans], dtype=float)
    return {
        "shooting_impulses": len(plans),
        "shooting_paper_chosen": sum(p.chosen == "paper" for p in plans),
        "shooting_predicted_median_h": float(np.median(pred)),
        "shooting_paper_predicted_median_h": float(np.nanmedian(paper)) if np.isfinite(paper).any() else None,
        "shooting_rhs_evals_mean": float(evals.mean()),
        "shooting_rhs_evals_max": int(evals.max()),
    }

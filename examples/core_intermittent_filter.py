"""Intermittent safety filter on a planar single integrator, with the core API only.

A robot ``x_dot = u`` drives toward a goal past a disc. The intermittent filter stays off while the
robust barrier condition holds under the nominal command, turns on at ``Xi_on <= 0``, pushes the
barrier up at rate ``b``, and turns off at ``Xi_on >= c``. Run:

    python examples/core_intermittent_filter.py
"""

import numpy as np

from isf_robot.core import (
    DiscObstacleBarrier,
    IntermittentSafetyFilter,
    Linear,
    MetricsAccumulator,
    SingleIntegrator,
    miet_bound,
)


def main() -> None:
    goal = np.array([6.0, 0.0])
    obstacle = DiscObstacleBarrier(center=[3.0, 0.15], radius=0.7, name="disc")
    filt = IntermittentSafetyFilter(
        alpha=Linear(2.0), c=1.0, b=1.0, d_bar=0.0, system=SingleIntegrator(2), barriers=[obstacle]
    )
    x, dt = np.zeros(2), 0.01
    metrics = MetricsAccumulator()
    h_min = np.inf
    for k in range(1000):
        t = k * dt
        u_nom = goal - x
        u_nom *= min(1.0, 1.0 / max(np.linalg.norm(u_nom), 1e-9))  # at most 1 m/s
        step = filt.step(t, x, u_nom)
        if step.event is not None:
            print(f"t = {step.event.t:5.2f} s  filter {step.event.kind:3s}  (min Xi_on = {step.event.xi_min:+.3f})")
        metrics.add_step(step, dt)
        x = x + dt * step.u
        h_min = min(h_min, obstacle.value(x))
    m = metrics.result()
    # Constants for the MIET bound near the disc: |dXi/dx| <= 2|u| + 2 alpha R_ws with |u| <= 1,
    # workspace radius R_ws = 6 m around the disc centre, B = 1 m/s.
    print(f"final position {x.round(3)}, min h = {h_min:.4f} (>= 0: safe)")
    print(f"duty cycle {m.duty_cycle:.3f}, on-switches {m.on_switches}, QP solves {m.qp_solves}")
    print(f"MIET bound {miet_bound(1.0, 2 * 1.0 + 2 * 2.0 * 6.0, 1.0):.4f} s; "
          f"measured min off period {m.min_off_s if m.min_off_s is not None else 'n/a'}")


if __name__ == "__main__":
    main()

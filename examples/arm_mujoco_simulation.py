"""A MuJoCo simulation script written with the public arm API.

The Panda-like arm reaches through the goals of the ``panda_pole`` scene. The same episode
(same seed) runs three times: without a filter, with the standard safety filter at every
control step, and with the event-triggered intermittent filter. An observer watches the
intermittent run and prints its switches. Run:

    python examples/arm_mujoco_simulation.py

To run your own model, replace ``load_scene`` by ``load_scene_from_files("arm.xml",
"arm.toml")`` (the TOML schema is in ``models/README.md``).
"""

from isf_robot.arm import ArmSimulation, ArmStepRecord, calibrate_d_bar, load_scene
from isf_robot.core import Observer, SwitchEvent


class PrintSwitches(Observer):
    """Prints each switch of the filter and tracks the closest approach."""

    def __init__(self) -> None:
        self.closest = float("inf")

    def on_start(self, info):  # type: ignore[no-untyped-def]
        print(f"  {info['strategy']} on {info['scene']}: control period "
              f"{info['control_period'] * 1e3:.1f} ms, physics step {info['dt'] * 1e3:.1f} ms, "
              f"{len(info['names'])} barriers")

    def on_event(self, event: SwitchEvent) -> None:
        if event.index <= 4:  # the first few are enough to see the pattern
            print(f"    t = {event.t:6.3f} s  filter {event.kind:3s}  min Xi_on = "
                  f"{event.xi_min:+.3f}")

    def on_step(self, record: ArmStepRecord) -> None:
        self.closest = min(self.closest, record.true_min)  # (smallest dist - margin over the physics steps)


def main() -> None:
    scene = load_scene("panda_pole")
    cal = calibrate_d_bar(scene)  # tracking error of the torque controller, measured
    print(f"d_bar = {cal.d_bar:.3f} rad/s (99% quantile {cal.quantile_value:.3f} x {cal.factor})")

    results = {}
    for strategy in ("nominal", "cbf", "isf"):
        watch = PrintSwitches() if strategy == "isf" else None
        sim = ArmSimulation(scene, strategy, seed=0, d_bar=cal.d_bar,
                            observers=[watch] if watch else [])
        results[strategy] = sim.run(duration=8.0)
        if watch:
            print(f"    closest approach {watch.closest * 100:.1f} cm beyond the margin")

    print(f"\n{'strategy':9s} {'duty':>6s} {'switches':>8s} {'min h [m]':>10s} "
          f"{'collisions':>10s} {'goals':>5s} {'QP solves':>9s} {'wall [s]':>8s}")
    for name, r in results.items():
        print(f"{name:9s} {r.duty_cycle:6.3f} {r.on_switches:8d} {r.min_barrier:10.4f} "
              f"{r.collisions:10d} {r.goals_reached:5d} {r.qp_solves:9d} {r.wall_s:8.3f}")


if __name__ == "__main__":
    main()

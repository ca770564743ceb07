"""``isf-robot`` subcommands for bringing in one's own arm: ``init`` and ``check``.

* ``init --model ARM.xml``: a starter scene config for a model (joints with their actuator
  kind, colliding geoms by body, keyframes, a suggested ``max_joint_speed``), printed or written
  with ``--output`` (atomically);
* ``check --model SCENE.xml --config SCENE.toml`` (or ``--scene NAME``): the diagnostics of
  :mod:`isf_robot.arm.diagnostics` (contact at home, joint speeds the actuators cannot reach,
  servo chatter, distance accuracy of the pairs, goals out of reach) and, unless
  ``--no-calibration``, the tracking calibration's (saturation, a large ``d_bar``). Every
  finding says what to change; ``run`` and ``compare`` print the same warnings when they start.

Registered by :mod:`isf_robot.cli` through :func:`register`; handlers import MuJoCo lazily.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from isf_robot.core.exceptions import ConfigError, IsfError
from isf_robot.support.files import check_output_path, write_text_atomic

from .arm import _add_scene_args, _spec

__all__ = ["register", "print_findings"]


def register(subparsers: Any) -> None:
    """Add ``init`` and ``check`` to the CLI's subparsers."""
    p = subparsers.add_parser(
        "init", help="print a starter scene config (TOML) for your MJCF arm",
        description="Read an MJCF model and print a starter scene config: the actuated joints with "
                    "their actuator kind, the colliding geoms by body, the keyframes, the end "
                    "effector and a max_joint_speed the actuators allow. Add obstacles and goals, "
                    "then run `isf-robot check`.")
    p.add_argument("--model", required=True, metavar="PATH.xml", help="the MJCF file (your arm or scene)")
    p.add_argument("--output", metavar="PATH.toml", help="write the TOML here instead of printing it")
    p.set_defaults(handler=_cmd_init)

    p = subparsers.add_parser(
        "check", help="diagnose a scene before running it",
        description="Report what would silently cripple a run: robot geoms in contact at home, "
                    "max_joint_speed above what the actuators and joint damping allow, servo chatter, "
                    "inexact collision distances, goals out of reach, and (from the tracking "
                    "calibration) actuator saturation and a large d_bar. Each finding says what to "
                    "change.")
    _add_scene_args(p)
    p.add_argument("--no-calibration", action="store_true",
                   help="skip the tracking calibration (saturation and d_bar findings)")
    p.add_argument("--strict", action="store_true", help="exit with status 1 when anything is found")
    p.set_defaults(handler=_cmd_check)


def print_findings(findings: Any, file: Any = None) -> None:
    """One ``warning [code]: message`` line per finding, on stderr by default."""
    for f in findings:
        print(f"warning [{f.code}]: {f.message}", file=file if file is not None else sys.stderr)


def _cmd_init(args: argparse.Namespace) -> int:
    from isf_robot.arm.starter import starter_toml

    if args.output:
        out = check_output_path(args.output, "--output")
        if not out.parent.is_dir():
            raise ConfigError(f"--output {str(out)!r}: folder {str(out.parent)!r} does not exist")
    text = starter_toml(args.model)
    if args.output:
        write_text_atomic(args.output, text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        print(text, end="")
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    from isf_robot.arm.actuation import servo_lead
    from isf_robot.arm.calibration import calibrate_d_bar
    from isf_robot.arm.diagnostics import check_calibration, check_scene, filter_findings, speed_bounds
    from isf_robot.arm.filter_design import designed_blend, designed_options, with_design

    scene = _spec(args).load()
    findings = check_scene(scene)
    v, rules = speed_bounds(scene)
    print(f"scene {scene.name}: {scene.n_joints} joints {list(scene.joint_names)}, "
          f"{len(scene.robot_geom_ids)} robot geoms, {len(scene.obstacle_geom_ids)} obstacle geoms")
    for a in scene.arms:
        print(f"  arm {a.name}: joints {list(scene.joint_names[a.joints])}, {a.geom_ids.size} geoms, "
              f"{a.goals.stop - a.goals.start} goals")
    kinds = _kinds(scene)
    print(f"  actuators: {', '.join(f'{j} {k}' for j, k in zip(scene.joint_names, kinds))}")
    why = {"damping": " (damping)", "servo kv": " (servo kv)", "none": ""}
    print("  joint speed bounds [rad/s]: "
          + ", ".join(f"{j} {x:.3g}{why[r]}" for j, x, r in zip(scene.joint_names, v, rules))
          + f" (max_joint_speed = {scene.config.gains.max_joint_speed:g}; damping: (F - gravity) / damping, the "
            "steady speed, checked; servo kv: (F - gravity) / kv on an undamped joint, the largest velocity step "
            "the servo answers unsaturated, init's conservative suggestion)")
    lead = servo_lead(scene)
    spec, named = with_design(scene.config, lead=lead), designed_options(scene.config, scene.config.filter, lead)
    by_lead = "blend" in named and lead > designed_blend(scene.config)
    print(f"  intermittent filter: hand-over blend = {spec.blend:.3g} s, predictive horizon = {spec.horizon:.3g} s"
          + (f" ({' and '.join(sorted(named))} designed from "
             + ("the position servos' time constant (gear^2 kv + damping) / (gear^2 kp)" if by_lead else
                "[gains] max_joint_speed / max_joint_acc")
             + " and [control] period; models/README.md)" if named else " (from [filter])"))
    findings += filter_findings(scene)
    if not args.no_calibration:
        cal = calibrate_d_bar(scene)
        print(f"  calibrated d_bar = {cal.d_bar:.4g} rad/s ({cal.samples} physics steps; "
              f"saturation {', '.join(f'{s:.0%}' for s in cal.saturation)})")
        findings += check_calibration(scene, cal)
    if findings:
        print(f"{len(findings)} finding(s):")
        print_findings(findings, file=sys.stdout)
    else:
        print("no findings")
    return 1 if findings and args.strict else 0


def _kinds(scene: Any) -> list[str]:
    from isf_robot.arm.actuation import actuator_info

    out = []
    for j, a in zip(scene.joint_names, scene.actuator_ids):
        try:
            out.append(actuator_info(scene.model, int(a), j).kind if a >= 0 else "none")
        except IsfError:
            out.append("unsupported")
    return out

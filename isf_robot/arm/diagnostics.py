"""Diagnostics of a scene before a run: what silently cripples a filter on a user's own arm.

Each check returns :class:`Finding` s whose message names the cause and says what to change:

* ``self-contact``: robot geoms in contact at home that no contact filter covers (MuJoCo's
  parent-child filter does not apply to bodies welded to the world, e.g. a base geom against
  link 1): the arm starts in permanent contact and the calibration measures contact forces;
* ``home-contact``: the arm touches another geom (an obstacle) at home;
* ``joint-speed``: ``[gains] max_joint_speed`` above what a joint's actuator limit and damping
  allow, ``(F - |gravity at home|) / damping`` per joint;
* ``saturation``: arm actuators at their limit in the calibration (a fraction of its steps);
* ``d-bar``: a calibrated ``d_bar`` large relative to ``max_joint_speed``; the message names the
  arm's joint friction (``dof_frictionloss``) and armature with their values when it has any;
* ``servo-chatter``: a force-limited servo whose damping ``kv`` is too stiff for the timestep
  (``kv dt / M_ii > 2``): once the force limit clips it, the step is explicit in it and the
  joint chatters at the limit;
* ``capsule-box``: pairs whose ``mj_geomDistance`` depth is not a signed distance;
* ``ccd-tolerance``: pairs computed by GJK/EPA (meshes, cylinders, ellipsoids) with a loose
  ``<option ccd_tolerance>``;
* ``goal-reach``: goals farther than the arm reaches, or not reached by inverse kinematics
  within the joint limits (obstacles ignored).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from isf_robot.core.chatter import chatter_risk

from .actuation import actuator_info, servo_lead, speed_bound
from .arms import geom_arms
from .calibration import Calibration, calibrate_d_bar
from .filter_design import with_design
from .one_arm import arm_scene
from .pairs import collision_pairs
from .records import FilterParams
from .scene import Scene
from .selection import geom_label, subtree_bodies

__all__ = ["Finding", "check_scene", "check_calibration", "run_findings", "joint_speed_limits", "speed_bounds",
           "goal_name", "SATURATION_LIMIT", "D_BAR_RATIO", "CCD_TOLERANCE"]

SATURATION_LIMIT = 0.01
"""Largest fraction of calibration steps an arm actuator may spend at its limit unreported."""
D_BAR_RATIO = 0.2
"""``d_bar / max_joint_speed`` above which a calibrated ``d_bar`` is reported."""
CCD_TOLERANCE = 1e-8
"""Largest ``ccd_tolerance`` [m] for pairs through GJK/EPA (the shipped scenes use 1e-10)."""

_G = mujoco.mjtGeom
_GJK = {int(_G.mjGEOM_MESH), int(_G.mjGEOM_CYLINDER), int(_G.mjGEOM_ELLIPSOID), int(_G.mjGEOM_SDF),
        int(_G.mjGEOM_HFIELD)}
_CAPSULE_BOX = {int(_G.mjGEOM_CAPSULE), int(_G.mjGEOM_BOX)}


@dataclass(frozen=True)
class Finding:
    """One diagnostic: ``code`` (see the module docstring) and a one-paragraph ``message``."""

    code: str
    message: str

    def __str__(self) -> str:
        return f"{self.code}: {self.message}"


def _body(model: mujoco.MjModel, b: int) -> str:
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or ("world" if b == 0 else f"body{b}")


def _arm_bodies(scene: Scene) -> set[int]:
    """Bodies moved by an arm joint."""
    out: set[int] = set()
    for j in scene.joint_ids:
        out.update(subtree_bodies(scene.model, int(scene.model.jnt_bodyid[j])))
    return out


def _home_contacts(scene: Scene) -> list[Finding]:
    model = scene.model
    data = mujoco.MjData(model)
    data.qpos[scene.qpos_adr] = scene.home
    scene.set_moving_obstacles(data, 0.0)
    mujoco.mj_forward(model, data)
    arm = _arm_bodies(scene)
    robot = set(scene.robot_geom_ids.tolist())
    obstacles = set(scene.obstacle_geom_ids.tolist())
    out, seen = [], set()
    for c in data.contact[: data.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
        if c.dist >= 0 or not ({b1, b2} & arm or {g1, g2} & robot) or (g1, g2) in seen:
            continue
        seen.add((g1, g2))
        pair = f"{geom_label(model, g1)!r} (body {_body(model, b1)!r}) and {geom_label(model, g2)!r} " \
               f"(body {_body(model, b2)!r})"
        depth = f"{-c.dist * 1000:.1f} mm deep"
        if {g1, g2} & obstacles:
            out.append(Finding("home-contact", f"at home the arm touches an obstacle: {pair}, {depth}; "
                                               "move the obstacle or choose another home"))
            continue
        world = [_body(model, b) for b in (b1, b2) if model.body_weldid[b] == 0]
        why = (f" (body {world[0]!r} is fixed to the world, so MuJoCo's parent-child contact filter "
               "does not apply)" if world else "")
        out.append(Finding(
            "self-contact",
            f"robot geoms in contact at home: {pair}, {depth}{why}. The arm starts in permanent "
            "contact: its tracking fights the contact force and the calibrated d_bar measures it. "
            f"If these bodies may not touch, add <contact><exclude body1=\"{_body(model, b1)}\" "
            f"body2=\"{_body(model, b2)}\"/></contact> to the scene file that includes the arm "
            "(no edit of the arm's file needed), or shrink or move one of the geoms"))
    return out


def joint_speed_limits(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Per arm joint: the steady speed the actuator limit and joint damping allow, and gravity.

    Returns:
        ``(v_max, gravity)``: ``v_max = (F - |g|) / b`` [rad/s] (F the actuator's torque limit,
        ``|g|`` the gravity torque at home, b the joint damping; ``inf`` without damping or
        limit, 0 when the actuator cannot hold the arm at home), and ``|g|`` [N m].

    """
    model = scene.model
    data = mujoco.MjData(model)
    data.qpos[scene.qpos_adr] = scene.home
    mujoco.mj_forward(model, data)
    grav = np.abs(data.qfrc_bias[scene.dof_adr])
    damping = model.dof_damping[scene.dof_adr]
    F = scene.torque_limit
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where((damping > 0) & np.isfinite(F), np.maximum(F - grav, 0.0) / damping, np.inf)
    return v, grav


def speed_bounds(scene: Scene) -> tuple[np.ndarray, list[str]]:
    """Per arm joint, the speed its actuator allows and the rule (:func:`~isf_robot.arm.actuation.speed_bound`).

    Unlike :func:`joint_speed_limits` (the damping's steady speed, which the ``joint-speed`` check holds
    ``max_joint_speed`` to), a servo on an undamped joint gets the largest velocity step it answers within
    its force range: what ``isf-robot init`` bases its suggestion on.
    """
    _, grav = joint_speed_limits(scene)
    out, rules = np.full(scene.n_joints, np.inf), []
    for i, a in enumerate(scene.actuator_ids):
        try:
            info = actuator_info(scene.model, int(a)) if a >= 0 else None
        except ValueError:
            info = None
        out[i], rule = speed_bound(info, float(scene.torque_limit[i]), float(scene.model.dof_damping[scene.dof_adr[i]]),
                                   float(grav[i]))
        rules.append(rule)
    return out, rules


def _speed(scene: Scene) -> list[Finding]:
    vmax = scene.config.gains.max_joint_speed
    v, grav = joint_speed_limits(scene)
    bad = [i for i in range(scene.n_joints) if vmax > v[i]]
    if not bad:
        return []
    damping = scene.model.dof_damping[scene.dof_adr]
    per = "; ".join(f"{scene.joint_names[i]}: {v[i]:.3g} rad/s (limit {scene.torque_limit[i]:g} N m, "
                    f"gravity {round(float(grav[i]), 2):g} N m, damping {damping[i]:g} N m s/rad)" for i in bad)
    suggest = 0.8 * float(np.min(v))
    return [Finding(
        "joint-speed",
        f"[gains] max_joint_speed = {vmax:g} rad/s is more than the arm can move: {per}. Commands "
        "above that saturate the actuators, the calibrated d_bar grows and goals are missed; set "
        f"[gains] max_joint_speed = {suggest:.2g} (80% of the slowest joint's limit)")]


def _servo_chatter(scene: Scene) -> list[Finding]:
    model = scene.model
    data = mujoco.MjData(model)
    data.qpos[scene.qpos_adr] = scene.home
    mujoco.mj_forward(model, data)
    mdiag = data.M[(model.M_rowadr + model.M_rownnz - 1)[scene.dof_adr]]
    dt = float(model.opt.timestep)
    bad, dt_ok = [], dt
    for i, a in enumerate(scene.actuator_ids):
        if a < 0 or not model.actuator_forcelimited[a]:
            continue
        try:
            info = actuator_info(model, int(a))
        except ValueError:
            continue  # an unsupported actuator: make_actuation reports it
        kv = info.gear ** 2 * info.kv
        if kv * dt / mdiag[i] > 2.0:
            bad.append(f"{scene.joint_names[i]} (kv {kv:g} N m s/rad, inertia {mdiag[i]:.3g} kg m^2: "
                       f"kv dt / M = {kv * dt / mdiag[i]:.2g})")
            dt_ok = min(dt_ok, 2.0 * float(mdiag[i]) / kv)
    if not bad:
        return []
    nice = max(x for x in (1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5) if x < dt_ok or x == 1e-5)
    return [Finding(
        "servo-chatter",
        f"force-limited servos too stiff for timestep {dt:g} s: {'; '.join(bad)}. When the force "
        "limit clips such a servo, MuJoCo's step is explicit in its damping and the joint chatters "
        "at the limit (the calibration then reports saturation and a large d_bar); set "
        f"<option timestep=\"{nice:g}\"/> in the scene file (and a [control] period that is a "
        "multiple of it)")]


def _pairs(scene: Scene) -> list[Finding]:
    model, bc = scene.model, scene.config.barrier
    pairs = collision_pairs(model, scene.robot_geom_ids, scene.obstacle_geom_ids, margin=bc.margin,
                            self_collision=scene.config.robot.self_collision, self_margin=bc.self_margin,
                            arm_of=geom_arms(scene.arms, scene.robot_geom_ids) if scene.arms else None)
    box_obstacle, box_robot, gjk = [], [], []
    obstacles = set(scene.obstacle_geom_ids.tolist())
    for name, a, b in zip(pairs.names, pairs.geom1, pairs.geom2):
        types = {int(model.geom_type[a]), int(model.geom_type[b])}
        if types == _CAPSULE_BOX:
            the_box = a if int(model.geom_type[a]) == int(_G.mjGEOM_BOX) else b
            (box_obstacle if int(the_box) in obstacles else box_robot).append(name)
        elif types & _GJK:
            gjk.append(name)
    out = []
    why = ("MuJoCo's capsule-box collider does not return a signed distance once the geoms "
           "overlap, so the barrier gradient is wrong there")
    if box_obstacle:
        out.append(Finding(
            "capsule-box",
            f"pairs {box_obstacle}: {why}; model the obstacle box as an 8-vertex convex mesh "
            "(routed through GJK/EPA, exact with a tight ccd_tolerance)"))
    if box_robot:
        out.append(Finding(
            "capsule-box",
            f"pairs {box_robot} (the box is the arm's, e.g. a vendor's fingertip pads): {why}; "
            "leave those geoms out of [robot] (select by bodies or geoms instead of the whole "
            "subtree), or give the obstacle another shape than a capsule (a convex mesh or a "
            "cylinder; the arm's file needs no edit)"))
    tol = float(model.opt.ccd_tolerance)
    if gjk and tol > CCD_TOLERANCE:
        out.append(Finding(
            "ccd-tolerance",
            f"{len(gjk)} pairs go through GJK/EPA (meshes, cylinders, ellipsoids), e.g. {gjk[:3]}, "
            f"and ccd_tolerance is {tol:g} m: distances and gradients are only that accurate; add "
            "<option ccd_tolerance=\"1e-10\"/> to the scene file"))
    return out


def _goals(scene: Scene, iterations: int = 300) -> list[Finding]:
    if scene.arms:  # (each arm's goals by its own end effector)
        return [f for i in range(len(scene.arms)) for f in _goals(arm_scene(scene, i), iterations)]
    model = scene.model
    data = mujoco.MjData(model)
    data.qpos[scene.qpos_adr] = scene.home
    mujoco.mj_kinematics(model, data)
    out = []
    # reach bound: distances between consecutive hinge axis points, and the last to the ee
    hinge = all(int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE) for j in scene.joint_ids)
    order = sorted(scene.joint_ids.tolist(), key=lambda j: len(_ancestors(model, int(model.jnt_bodyid[j]))))
    pts = [data.xanchor[j].copy() for j in order] + [np.array(scene.ee_position(data))]
    reach = sum(float(np.linalg.norm(pts[i + 1] - pts[i])) for i in range(len(pts) - 1))
    tol = scene.config.task.tolerance
    lo, hi = scene.joint_range[:, 0], scene.joint_range[:, 1]
    jac = np.zeros((3, model.nv))
    ee_home = pts[-1]
    for i, goal in enumerate(scene.goal_positions):
        name = goal_name(scene, i)
        dist = float(np.linalg.norm(goal - pts[0]))
        from_home = float(np.linalg.norm(goal - ee_home))
        if hinge and dist > reach + tol:
            out.append(Finding(
                "goal-reach",
                f"{name} at {np.round(goal, 3).tolist()} is {dist:.3f} m from the first joint's axis "
                f"({np.round(pts[0], 3).tolist()}); the arm reaches at most {reach:.3f} m: move the goal"))
            continue
        q = scene.home.copy()
        closest = from_home
        for _ in range(iterations):
            data.qpos[scene.qpos_adr] = q
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            err = goal - scene.ee_position(data)
            closest = min(closest, float(np.linalg.norm(err)))
            if closest < 0.2 * tol:
                break
            scene.ee_jacobian(data, jac)
            J = jac[:, scene.dof_adr]
            q = np.clip(q + J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(3), err), lo, hi)
        if closest > tol:
            out.append(Finding(
                "goal-reach",
                f"{name} at {np.round(goal, 3).tolist()} is not reached by inverse kinematics from home within "
                f"the joint limits (obstacles ignored): the end effector came no closer than {closest:.3f} m "
                f"(it starts {from_home:.3f} m away at home; tolerance {tol:g} m): move the goal or check the "
                "joint ranges"))
    return out


def goal_name(scene: Scene, i: int) -> str:
    """How messages name goal ``i`` (from 0): ``goal 2 ('goal_b')`` from 1, with its site when it has one."""
    goals = scene.config.task.goals
    site = goals[i].site if i < len(goals) else None
    return f"goal {i + 1}" + (f" ({site!r})" if site else "")


def _ancestors(model: mujoco.MjModel, b: int) -> list[int]:
    out = []
    while b != 0:
        b = int(model.body_parentid[b])
        out.append(b)
    return out


def check_scene(scene: Scene) -> list[Finding]:
    """Every check that needs no simulation (see the module docstring), in a fixed order."""
    return _home_contacts(scene) + _speed(scene) + _servo_chatter(scene) + _pairs(scene) + _goals(scene)


def filter_findings(scene: Scene) -> list[Finding]:
    """The scene's own intermittent-filter parameters (``[filter]`` and the design): a chatter risk.

    Reported by ``isf-robot check``, not before every run (a standard filter's run does not use them).
    """
    risk = chatter_risk(with_design(scene.config, lead=servo_lead(scene)), scene.config.control.period)
    if risk is None:
        return []
    return [Finding("chatter-risk", f"[filter]: {risk}")]


def check_calibration(scene: Scene, cal: Calibration, d_bar: float | None = None) -> list[Finding]:
    """Findings of a tracking calibration: actuator saturation and a large ``d_bar``.

    Args:
        scene: The scene.
        cal: Its calibration.
        d_bar: The ``d_bar`` the run uses (default the calibrated one).

    """
    out = []
    names = cal.joint_names or scene.joint_names
    sat = [(names[i], s) for i, s in enumerate(cal.saturation) if s > SATURATION_LIMIT]
    if sat:
        per = ", ".join(f"{n} {s:.0%}" for n, s in sat)
        out.append(Finding(
            "saturation",
            f"during the d_bar calibration these arm actuators were at their force/torque limit "
            f"({per} of {cal.samples} physics steps): d_bar then measures the actuators' limits, not "
            "the tracking. Lower [gains] max_joint_speed (and max_joint_acc), or give the actuators "
            "the robot's real limits (forcerange / ctrlrange)"))
    return out + _d_bar(scene, cal.d_bar if d_bar is None else d_bar, cal.friction_fed_forward)


def _per_joint(scene: Scene, values: np.ndarray, unit: str) -> str:
    return ", ".join(f"{j} {v:.3g}" for j, v in zip(scene.joint_names, values) if v > 0) + f" {unit}"


def _d_bar(scene: Scene, d: float, friction_fed_forward: bool = True) -> list[Finding]:
    vmax = scene.config.gains.max_joint_speed
    if d <= D_BAR_RATIO * vmax:
        return []
    model = scene.model
    fric = model.dof_frictionloss[scene.dof_adr]
    arm = model.dof_armature[scene.dof_adr]
    causes = ("Usual causes: actuator saturation, contact at home, max_joint_speed above what the joints "
              "allow, low tracking gains")
    if np.any(fric > 0):
        how = ("the low-level tracker feeds it forward (f tanh(u / v_s)); what is left is friction the "
                "model's soft friction constraint adds beyond it" if friction_fed_forward else
                "it was not fed forward in this calibration: calibrate with the tracker's friction "
                "compensation on (the default)")
        causes = (f"This arm has joint friction (dof_frictionloss: {_per_joint(scene, fric, 'N m')}): each "
                  f"command lags by the friction torque over the tracking gain; {how}. Other causes: "
                  "actuator saturation, contact at home, max_joint_speed above what the joints allow, low "
                  "tracking gains")
    if np.any(arm > 0):
        causes += f"; armature (dof_armature: {_per_joint(scene, arm, 'kg m^2')}) slows the joints it is added to"
    return [Finding(
        "d-bar",
        f"d_bar = {d:.3g} rad/s is {d / vmax:.0%} of max_joint_speed = {vmax:g} rad/s: the robust "
        "term |dh/dq| d_bar makes the filter brake far from obstacles and the arm reaches few goals. "
        f"{causes}; fix the cause rather than d_bar (well-tracked arms here calibrate "
        f"to under {D_BAR_RATIO / 2:.0%} of max_joint_speed)")]


def run_findings(scene: Scene, params: FilterParams) -> list[Finding]:
    """What a run should warn about before it starts.

    :func:`check_scene`, then the calibration's findings when ``d_bar`` was calibrated (the
    cached calibration), else the ``d_bar`` check.
    """
    out = check_scene(scene)
    if params.d_bar_source == "calibration":
        return out + check_calibration(scene, calibrate_d_bar(scene), params.d_bar)
    return out + _d_bar(scene, params.d_bar)

"""Plan-time joint-space check: follow a timed SE(3) plan the way the controller will.

The composition is planned in SE(3) (the paper's Section 5 admits the result may not be
executable). Before a plan is promised, :class:`JointPathChecker` follows it
kinematically with the controller's own differential-IK law
(:class:`~drake_lfd.robot.differential_ik_law.DifferentialIKLaw`, same period, gain and
limits; measured = commanded positions), from a start configuration, and checks at every
step. A plan takes some 1,500 steps (the slow geometric pass), so each step's pose and
Jacobian come from the UR5e's DH table in plain floats in the base frame
(:mod:`~drake_lfd.robot.dh_kinematics`, equal to the plant's to 1e-14) and the plan's
poses and velocities are sampled for all steps at once in numpy, not from a Drake
``PiecewisePose`` step by step; the law's closed form is its own. Where it does not apply
(a rotation error beyond 90 degrees, a singular Jacobian) the step is the law's own on
the plant, QP included. On the paper's trials the joint paths equal those of the law on
the plant to 1e-8 rad (rounding, compounded over the steps), with the same verdicts.
The checks:

- **joint limits**: the law keeps the command inside them by slowing the motion; when
  that makes E fall behind the plan by more than the path tolerance, the joint whose
  limit bound is named;
- **singularities**, the UR5e's three: elbow straight (``|sin q3|`` below
  ``elbow_margin``), wrist aligned (``|sin q5|`` below ``wrist_margin``) and wrist centre
  on the shoulder axis (``|a2 cos q2 + a3 cos(q2 + q3) + d5 sin(q2 + q3 + q4)|``, the
  wrist point's distance from the shoulder axis in the arm's plane, below
  ``shoulder_margin_m``). The Jacobian's determinant is ``a2 a3 sin q3 sin q5`` times
  that distance, so these are exactly where it vanishes; near them joint speeds blow up
  for ordinary tool motions;
- **clearance**: every robot and tool geometry at least ``clearance_m`` from every
  obstacle, safety shell and the table (the base and shoulder links, which stand on the
  table, are not checked against it), with Drake's signed distances; pairs the motion
  bound (:mod:`~drake_lfd.robot.motion_bounds`) proves far are skipped;
- **reach**: E within the success tolerances (5 mm, 2 deg) of each critical
  configuration when it is due, and within the path tolerance (5 cm, 15 deg) everywhere.

It stops at the first violation and says which it was, when, and in which span (a
:class:`~drake_lfd.robot.joint_path_records.Blocker`; the margins are those of
:class:`~drake_lfd.robot.joint_path_records.JointPathLimits`). A configuration beyond
the arm's reach (farther from the shoulder than the arm's links and tool together) is
refused before following anything.

Start configurations and windings: :meth:`JointPathChecker.follow_from_candidates`
tries the inverse-kinematics branches of the first pose, best first, and for each the
2 pi windings of the joints that can turn more than a full circle (all six on the
UR5e), shifting the start by one turn away from a limit the path ran into; the whole
plan decides, not con_1 alone.

Reuse: a checker remembers its last follows (``follow_memory.py``) with the loop's
whole state at the start of each span. A plan identical to one of them (times, poses,
critical indices, to the bit) up to a critical configuration, from the same start,
resumes there: the lazy search's next composition re-follows only the spans after the
one it changed, and a trial of a task whose first spans do not depend on its variables
only the rest. The steps before a critical configuration interpolate only the samples
up to it, so the result is the full follow's, to the bit, whichever plans were followed
before.

Not for: choosing a composition (``planning/``), simulating the robot (``diagrams/``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from drake_lfd.core.dual_quaternion import rotation_from_dual_quaternion, translation_from_dual_quaternion
from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion
from drake_lfd.core.quaternion import (
    quaternion_conjugate,
    quaternion_from_rotation_vector,
    quaternion_multiply,
    rotation_vector_from_quaternion,
)
from drake_lfd.core.exact_memo import ExactMemo
from drake_lfd.core.timing import TimedPlan
from drake_lfd.robot.differential_ik_law import (
    DEFAULT_POSITION_GAIN,
    DEFAULT_TIME_STEP_S,
    DEFAULT_VELOCITY_LIMIT_FRACTION,
    DifferentialIKLaw,
    pose_error,
)
from drake_lfd.robot.initial_ik import UnreachableConfigurationError, initial_configuration_candidates
from drake_lfd.robot.dh_kinematics import DHArm, rotation_error, rotation_matrices, shoulder_singularity_distance
from drake_lfd.robot.follow_memory import FollowCheckpoint, FollowMemory, FollowRecord
from drake_lfd.robot.joint_path_records import (
    Blocker,
    JointPath,
    JointPathLimits,
    describe_clearance_shortfall,
    singularity_shortfall,
)
from drake_lfd.robot.kinematics import (
    BASE_FRAME_NAME,
    END_EFFECTOR_FRAME_NAME,
    TOOL0_FRAME_NAME,
    UR5E_JOINT_NAMES,
    UR5eKinematics,
)
from drake_lfd.robot.motion_bounds import motion_bounds
from drake_lfd.robot.pan_only import pan_only_configuration
from drake_lfd.robot.path_constraints import (
    allowed_deviation,
    constraint_rotation,
    constraint_window,
    describe_deviation,
    orientation_deviations,
)
from drake_lfd.robot.scene import ON_TABLE_LINKS, KinematicScene

__all__ = ["JointPathChecker"]

# Poses whose inverse-kinematics branches a checker remembers (a 20-configuration task's
# candidates are a few hundred).
_REMEMBERED_POSES = 1024


class JointPathChecker:
    """Follows timed plans kinematically in a scene and reports the first violation.

    Parameters
    ----------
    scene : KinematicScene
        The robot (with its tool) and the boxes; its plant also serves the law.
    X_WB : RigidTransform, optional
        The robot base (for the preferred inverse-kinematics posture).
    table_geometry_ids : sequence of GeometryId, optional
        Boxes to check all links but the base and shoulder against (the table).
    limits : JointPathLimits
    time_step, position_gain, velocity_limit_fraction : float
        The controller's (defaults: the closed loop's).
    """

    def __init__(self, scene, *, X_WB: RigidTransform | None = None, table_geometry_ids: Sequence = (),
                 limits: JointPathLimits = JointPathLimits(),
                 time_step: float = DEFAULT_TIME_STEP_S, position_gain: float = DEFAULT_POSITION_GAIN,
                 velocity_limit_fraction: float = DEFAULT_VELOCITY_LIMIT_FRACTION):
        self.scene = scene
        self.X_WB = RigidTransform() if X_WB is None else RigidTransform(X_WB)
        self.limits = limits
        self._branches = ExactMemo(maxsize=_REMEMBERED_POSES)
        self._starts = ExactMemo(maxsize=_REMEMBERED_POSES)
        # The last follows from each start, to resume plans sharing a prefix.
        self._follows = FollowMemory()
        # Answers the planning layer derives from this scene alone, kept with the checker
        # (built once per scene) so that later plans in it reuse them: the planner's twist
        # orders (planning/planner.py) and the refusals' pan-only rows and sweep
        # (planning/refusals.py).
        self.twist_orders = ExactMemo(maxsize=256)
        self.pan_memo: dict = {}
        plant = scene.plant
        self.law = DifferentialIKLaw(
            plant=plant, model=scene.model, frame_E=plant.GetFrameByName(END_EFFECTOR_FRAME_NAME),
            time_step=time_step, position_gain=position_gain, velocity_limit_fraction=velocity_limit_fraction)
        self.time_step = self.law.time_step
        geometry = scene.geometry
        inspector = scene.scene_graph.model_inspector()
        robot_ids = list(geometry.robot_geometry_ids)
        boxes = list(geometry.keep_out_geometry_ids)
        table_ids = [g for g in table_geometry_ids if g not in boxes]
        pairs = [(r, b) for b in boxes for r in robot_ids]
        for table in table_ids:
            pairs += [(r, table) for r in robot_ids
                      if geometry.names.get(r, "").split("/")[0] not in ON_TABLE_LINKS]
        self._pairs = pairs
        # Pairs of a shape placed by shoulder_pan alone: measured at its configuration
        # (robot/pan_only.py), as the scene and the refusals' pan sweep measure them.
        pan_only = {robot_ids[i] for i in scene.pan_only_rows}
        self._pan_only_pair = [r in pan_only for r, _ in pairs]
        bounds = {r: motion_bounds(plant, inspector, r) for r in robot_ids}
        # (pairs, joints) motion bounds; a pair without one is always measured.
        self._pair_bounds = np.array([np.where(np.isfinite(bounds[r]), bounds[r], 0.0) for r, _ in pairs]
                                     ).reshape(len(pairs), len(self.law.position_lower))
        self._pair_unbounded = np.array([not np.all(np.isfinite(bounds[r])) for r, _ in pairs], dtype=bool)
        # Per joint, the largest bound over the pairs: the scalar bound of the fast path.
        self._max_bounds = (self._pair_bounds.max(axis=0) if pairs else np.zeros(len(self.law.position_lower))).tolist()
        self._any_unbounded = bool(self._pair_unbounded.any())
        self._table_ids = set(table_ids)
        self._scene_graph_context = scene.scene_graph.GetMyContextFromRoot(scene.context)
        self._lower, self._upper = self.law.position_lower, self.law.position_upper
        # The arm's DH kinematics in its base frame B (the plant's own base and E frames).
        context = plant.CreateDefaultContext()
        X_WB_plant = plant.CalcRelativeTransform(context, plant.world_frame(),
                                                 plant.GetFrameByName(BASE_FRAME_NAME, scene.model))
        X_tool0_E = plant.CalcRelativeTransform(context, plant.GetFrameByName(TOOL0_FRAME_NAME, scene.model),
                                                plant.GetFrameByName(END_EFFECTOR_FRAME_NAME))
        self._arm = DHArm(X_tool0_E)
        self._R_BW = X_WB_plant.rotation().matrix().T
        self._p_WB = X_WB_plant.translation()

    @functools.cached_property
    def kinematics(self) -> UR5eKinematics:
        """Kinematics of the scene's arm (base and E), for timing its paths."""
        workcell = self.scene.workcell
        return UR5eKinematics(X_WB=workcell.X_WB, X_tool0_E=workcell.X_tool0_E)

    @classmethod
    def for_workcell(cls, workcell, **kwargs) -> "JointPathChecker":
        """A checker of ``workcell``'s scene (robot base, tool, table, obstacles and
        shells); ``kwargs`` are the constructor's (``limits``, ``time_step``, ...)."""
        scene = KinematicScene(workcell)
        table = [] if scene.geometry.table_geometry_id is None else [scene.geometry.table_geometry_id]
        return cls(scene, X_WB=workcell.X_WB, table_geometry_ids=table, **kwargs)

    # -- one follow ----------------------------------------------------------------------
    def follow(self, plan: TimedPlan, q_start: np.ndarray, *, path_constraints: Sequence = ()) -> JointPath:
        """Follows ``plan`` from ``q_start`` (6,); see the module docstring.

        ``path_constraints``: the task's (:class:`~drake_lfd.core.tasks.PathConstraint`),
        measured on the commanded joints over the spans each covers; the first sample
        turning the tool further than a constraint allows (its tolerance less the closed
        loop's tracking margin, :mod:`~drake_lfd.robot.path_constraints`) blocks the path
        like a collision, with reason ``path_constraint``.

        A plan this checker followed before from the same start, identical (times,
        poses, critical indices) up to one of its critical configurations, is resumed
        from the state the loop had there
        (:class:`~drake_lfd.robot.follow_memory.FollowCheckpoint`): the law is
        deterministic, so the result equals a full follow to the bit.
        """
        path = self._follow(plan, np.array(q_start, dtype=float))
        return self._held_to(path, plan, path_constraints) if path_constraints else path

    def _follow(self, plan: TimedPlan, q_start: np.ndarray) -> JointPath:
        limits, law, dt = self.limits, self.law, self.time_step
        critical_indices = tuple(int(i) for i in plan.critical_indices)
        plan_times, plan_poses = np.array(plan.times, dtype=float), np.array(plan.poses, dtype=float)
        record, checkpoint = self._follows.reusable(q_start, critical_indices, plan_times, plan_poses)
        if checkpoint is None and record is not None:
            return record.path  # the same plan from the same start
        duration = plan.duration
        due = [float(plan.times[i]) for i in critical_indices]
        X_cons = [RigidTransform(T) for T in matrices_from_dual_quaternion(plan.poses[list(critical_indices)])]
        steps = int(math.ceil(duration / dt - 1e-9)) + limits.settle_steps
        # The loop's state at the first sample of each span (con 2 on): where a later
        # plan sharing the prefix resumes.
        checkpoint_at = {int(math.ceil(d / dt - 1e-9)): c for c, d in enumerate(due) if c > 0}
        checkpoints: dict[int, FollowCheckpoint] = {}
        if checkpoint is None:
            first = 0
            q = q_start.tolist()
            times, path, clearances, critical_errors = [], [], [], []
            wake = np.full(len(self._pairs), -np.inf)
            travel = [0.0] * len(q)
            q_previous = q
            slack = -math.inf
            min_clearance, min_elbow, min_wrist, min_shoulder = math.inf, math.inf, math.inf, math.inf
            span, next_con = 0, 0
        else:
            first = checkpoint.k
            old = record.path
            times, path, clearances = list(old.t[:first]), list(old.q[:first]), list(old.clearances[:first])
            critical_errors = list(checkpoint.critical_errors)
            q, wake, travel = checkpoint.q.tolist(), checkpoint.wake.copy(), checkpoint.travel.tolist()
            q_previous, slack = list(checkpoint.q_previous), checkpoint.slack
            min_clearance, min_elbow, min_wrist, min_shoulder = checkpoint.minima
            span, next_con = checkpoint.span, checkpoint.next_con
            checkpoints = {c: point for c, point in record.checkpoints.items() if c <= checkpoint.con}
        blocker = None
        lower, upper = self._lower.tolist(), self._upper.tolist()
        # The desired pose and spatial velocity at every step, in B, in a few calls.
        desired = self._desired_in_base(plan, np.arange(first, steps + 1) * dt)
        for k in range(first, steps + 1):
            if k in checkpoint_at and k > first:
                c = checkpoint_at[k]
                checkpoints[c] = FollowCheckpoint(c, k, np.array(q), wake.copy(), np.array(travel), tuple(q_previous),
                                                 slack,
                                             (min_clearance, min_elbow, min_wrist, min_shoulder), span, next_con,
                                             tuple(critical_errors))
            t = k * dt
            times.append(t)
            path.append(tuple(q))  # (a tuple: see _desired_in_base)
            while span < len(due) - 2 and due[span + 1] <= t:
                span += 1
            # Singularities.
            q_list = q
            elbow, wrist = abs(math.sin(q_list[2])), abs(math.sin(q_list[4]))
            shoulder = abs(shoulder_singularity_distance(q_list))
            min_elbow, min_wrist, min_shoulder = min(min_elbow, elbow), min(min_wrist, wrist), min(min_shoulder, shoulder)
            if elbow < limits.elbow_margin or wrist < limits.wrist_margin or shoulder < limits.shoulder_margin_m:
                _kind, detail = singularity_shortfall(elbow, wrist, shoulder, limits)
                blocker = Blocker("singularity", detail, t, span)
                break
            # Clearance. ``slack``: how much more any pair's geometry may move before a
            # pair can come within the clearance (a scalar bound over all pairs, so most
            # steps skip the per-pair bookkeeping).
            step_travel = [abs(a - b) for a, b in zip(q_list, q_previous)]
            q_previous = q_list
            travel = [a + b for a, b in zip(travel, step_travel)]
            slack -= sum(r * d for r, d in zip(self._max_bounds, step_travel))
            if slack <= 0.0 or self._any_unbounded:
                clearance, pair, slack = self._clearance(q, np.array(travel), wake)
            else:
                clearance, pair = math.inf, None
            clearances.append(clearance)
            min_clearance = min(min_clearance, clearance)
            if clearance < limits.clearance_m:
                robot_id, box_id = pair
                names = self.scene.geometry
                what = "the table" if box_id in self._table_ids else names.describe(box_id)
                verb = describe_clearance_shortfall(what, clearance, limits.clearance_m)
                blocker = Blocker("collision", f"collision with {what}: {names.names.get(robot_id, robot_id)} {verb}",
                                  t, span, pair=(robot_id, box_id))
                break
            # Tracking: along the path, and at each critical configuration when due.
            # The step's law evaluates E's pose error at q: the tracking error.
            v, e = self._law_step(q, desired, k - first)
            position = math.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5])
            rotation = math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
            while next_con < len(due) and due[next_con] <= t + 1e-9:
                con_error = pose_error(X_cons[next_con], law.X_WE(np.array(q)))
                c_position, c_rotation = float(np.linalg.norm(con_error[3:])), float(np.linalg.norm(con_error[:3]))
                critical_errors.append((c_position, c_rotation))
                if c_position > limits.position_tolerance_m or c_rotation > limits.rotation_tolerance_rad:
                    blocker = self._tracking_blocker(
                        f"misses con_{next_con + 1} by {1000 * c_position:.1f} mm, {math.degrees(c_rotation):.1f} deg",
                        t, max(next_con - 1, 0), next_con + 1)
                    break
                next_con += 1
            if blocker is not None:
                break
            if position > limits.path_position_tolerance_m or rotation > limits.path_rotation_tolerance_rad:
                blocker = self._tracking_blocker(
                    f"falls {1000 * position:.0f} mm, {math.degrees(rotation):.1f} deg behind the plan", t, span)
                break
            if k == steps:
                break
            # One controller step (measured = commanded: kinematic).
            q = [x + dt * v_j for x, v_j in zip(q, v)]
            outside = [j for j, (x, a, b) in enumerate(zip(q, lower, upper)) if x < a - 1e-9 or x > b + 1e-9]
            if outside:
                blocker = Blocker("joint_limit", f"{UR5E_JOINT_NAMES[outside[0]]} reaches its limit", t, span)
                break
        clearances += [math.inf] * (len(times) - len(clearances))  # a sample stopped before its check
        result = JointPath(np.array(times), np.array(path), blocker, tuple(critical_errors),
                           min_clearance, min_elbow, min_wrist, min_shoulder, clearances=np.array(clearances))
        self._follows.remember(FollowRecord(q_start.tobytes(), critical_indices, plan_times, plan_poses, result,
                                           checkpoints))
        return result

    def _held_to(self, path: JointPath, plan: TimedPlan, constraints: Sequence) -> JointPath:
        """``path`` ended at the first sample that breaks one of ``constraints``, with that
        constraint as its blocker (naming the worst angle over the samples it covers up
        to the path's own end); ``path`` itself when none is broken first."""
        due = [float(plan.times[i]) for i in plan.critical_indices]
        R_WE = np.einsum("ij,mjk->mik", self._R_BW.T, self._arm.poses_batch(path.q)[:, :3, :3])
        first = None  # (sample, detail)
        for constraint in constraints:
            if constraint.kind != "orientation":
                continue
            window = np.flatnonzero(constraint_window(constraint, due, path.t))
            if not len(window):
                continue
            angles = orientation_deviations(R_WE[window], constraint_rotation(constraint))
            allowed = allowed_deviation(constraint)
            over = np.flatnonzero(angles > allowed)
            if len(over) and (first is None or window[over[0]] < first[0]):
                first = (int(window[over[0]]), describe_deviation(constraint, float(angles.max()), allowed))
        if first is None:
            return path
        k, detail = first
        t = float(path.t[k])
        span = max(0, min(int(np.searchsorted(due, t + 1e-9, side="right")) - 1, len(due) - 2))
        return dataclasses.replace(
            path, t=path.t[:k + 1], q=path.q[:k + 1], blocker=Blocker("path_constraint", detail, t, span),
            critical_errors=path.critical_errors[:sum(1 for d in due if d <= t + 1e-9)],
            clearances=None if path.clearances is None else path.clearances[:k + 1])

    def _desired_in_base(self, plan: TimedPlan, t: np.ndarray) -> tuple:
        """The plan at times ``t``, in the base frame B, a tuple of 18 floats per sample:
        E's rotation (nine, row by row), position (three) and spatial velocity (six, zero
        from the plan's end on); and the same in W as arrays ``(R (m, 3, 3), p (m, 3),
        V (m, 6))`` for the law's fallback. The plan is linear in position and slerped
        in rotation between its samples
        (:meth:`~drake_lfd.core.timing.TimedPlan.to_piecewise_pose`, evaluated here in
        numpy: equal to Drake's to 1e-15)."""
        times = np.asarray(plan.times, dtype=float)
        p_samples = translation_from_dual_quaternion(plan.poses)
        r_samples = rotation_from_dual_quaternion(plan.poses)
        tau = np.minimum(t, plan.duration)
        if len(times) < 2:
            segment, fraction = np.zeros(len(t), dtype=int), np.zeros(len(t))
            p_samples, r_samples, times = np.repeat(p_samples, 2, 0), np.repeat(r_samples, 2, 0), np.array([0.0, 1.0])
        else:
            segment = np.clip(np.searchsorted(times, tau, side="right") - 1, 0, len(times) - 2)
            fraction = (tau - times[segment]) / (times[segment + 1] - times[segment])
        dt = (times[1:] - times[:-1])[segment][:, None]
        p0, p1 = p_samples[segment], p_samples[segment + 1]
        p_W = p0 + fraction[:, None] * (p1 - p0)
        r0, r1 = r_samples[segment], r_samples[segment + 1]
        r1 = np.where(np.sum(r0 * r1, axis=1, keepdims=True) < 0.0, -r1, r1)  # the shorter way round
        relative = rotation_vector_from_quaternion(quaternion_multiply(r1, quaternion_conjugate(r0)))
        r_W = quaternion_multiply(quaternion_from_rotation_vector(fraction[:, None] * relative), r0)
        R_W = rotation_matrices(r_W)
        V_W = np.concatenate([relative / dt, (p1 - p0) / dt], axis=1)
        V_W[t >= plan.duration] = 0.0
        R_BW = self._R_BW
        in_base = np.concatenate([(R_BW @ R_W).reshape(len(t), 9), (p_W - self._p_WB) @ R_BW.T,
                                  V_W[:, :3] @ R_BW.T, V_W[:, 3:] @ R_BW.T], axis=1)
        # Tuples of floats leave the garbage collector's scans; the follow keeps them all.
        return list(map(tuple, in_base.tolist())), R_W, p_W, V_W

    def _law_step(self, q: list, desired: tuple, i: int) -> tuple[list, list]:
        """The law's joint velocity at ``q`` toward sample ``i`` of ``desired`` and the
        pose error (rotation, translation; its norms are the frame's own): the UR5e's
        DH kinematics in B in plain floats (:class:`~drake_lfd.robot.dh_kinematics.DHArm`,
        equal to the plant's to 1e-15) and the law's closed form; Drake's kinematics
        and QP where the closed form does not apply (the law's own
        :meth:`~drake_lfd.robot.differential_ik_law.DifferentialIKLaw.joint_velocity`)."""
        d = desired[0][i]  # R_d (9), p_d (3), V_d (6)
        R, p, J = self._arm.pose_and_jacobian(q)
        rotation = rotation_error(d, R)
        if rotation is not None:
            error = rotation + [d[9] - p[0], d[10] - p[1], d[11] - p[2]]
            gain = self.law.position_gain
            v = self.law.closed_form_step(q, J, [a + gain * b for a, b in zip(d[12:], error)])
            if v is not None:
                return v, error
        R_W, p_W, V_W = desired[1][i], desired[2][i], desired[3][i]
        q = np.array(q)
        v = self.law.joint_velocity(q, q, RigidTransform(RotationMatrix(R_W), p_W), V_W)
        return v.tolist(), self.law.last_pose_error.tolist()

    def _tracking_blocker(self, what: str, t: float, span: int, con: int | None = None) -> Blocker:
        """Why E fell behind: the limit that slowed the law's last step."""
        alpha, joint, kind = self.law.last_scale
        if kind == "position" and joint >= 0:
            return Blocker("joint_limit", f"E {what}: {UR5E_JOINT_NAMES[joint]} at its limit", t, span, con)
        if kind in ("speed", "qp"):
            name = UR5E_JOINT_NAMES[joint] if joint >= 0 else "a joint"
            return Blocker("singularity", f"E {what}: {name} would need more than its speed limit "
                           f"(singular Jacobian nearby)", t, span, con)
        return Blocker("reach", f"E {what}", t, span, con)

    def _clearance(self, q, travel, wake) -> tuple[float, tuple | None, float]:
        """Least signed distance over the pairs not proven far, its pair, and the slack:
        how far (in the units of the motion bounds) the joints may still travel before
        any pair must be measured again. Updates the pairs' wake-up travels in place
        (see ``motion_bounds``)."""
        if not self._pairs:
            return math.inf, None, math.inf
        moved = self._pair_bounds @ travel
        due = np.flatnonzero((moved >= wake) | self._pair_unbounded)
        if not len(due):
            return math.inf, None, float(np.min(wake - moved))
        best, best_pair = math.inf, None
        threshold = self.limits.clearance_m
        pan_only = self._pan_only_pair
        due_list = due.tolist()
        for at_pan_only in (False, True):
            group = [k for k in due_list if pan_only[k] == at_pan_only]
            if not group:
                continue
            signed_distance = self._query(pan_only_configuration(q) if at_pan_only else q)
            for k in group:
                pair = self._pairs[k]
                distance = signed_distance(*pair).distance
                # Stays beyond the clearance until its geometry has moved distance - clearance.
                wake[k] = moved[k] + distance - threshold
                if distance < best:
                    best, best_pair = distance, pair
        return best, best_pair, float(np.min(wake - moved))

    def _query(self, q):
        """The scene's signed-distance query with the arm at ``q``."""
        scene = self.scene
        scene.plant.SetPositions(scene.plant_context, scene.model, np.asarray(q, dtype=float))
        return scene.scene_graph.get_query_output_port().Eval(
            self._scene_graph_context).ComputeSignedDistancePairClosestPoints

    # -- candidates ----------------------------------------------------------------------
    def branches(self, X_WE: RigidTransform) -> list:
        """Every inverse-kinematics branch reaching ``X_WE``, best first
        (:func:`~drake_lfd.robot.initial_ik.initial_configuration_candidates` in closed
        form, with each branch's clearance); empty when none. Remembered per pose (the
        last :data:`_REMEMBERED_POSES`): the start and the refusal pre-check ask for the
        same poses, and trials of a task for its fixed configurations."""
        key = np.ascontiguousarray(X_WE.GetAsMatrix34()).tobytes()

        def solve():
            try:
                return initial_configuration_candidates(X_WE, X_WB=self.X_WB, scene=self.scene, method="closed_form")
            except UnreachableConfigurationError:
                return []
        return self._branches.get(key, solve)

    def start_candidates(self, X_WE: RigidTransform) -> list[np.ndarray]:
        """The inverse-kinematics branches reaching ``X_WE`` that a follow can start from,
        best first (the closed loop's initial configuration is the first): at the
        clearance from every obstacle, shell and the table and off every singularity
        margin, as the follow's first step checks them (a branch that breaks one would
        block every plan at its first step). Empty when none."""
        key = np.ascontiguousarray(X_WE.GetAsMatrix34()).tobytes()
        clearance = self.limits.clearance_m
        return self._starts.get(key, lambda: [
            c.q for c in self.branches(X_WE)
            if c.collision_free and c.min_distance_m >= clearance and self._first_step_passes(c.q)])

    def _first_step_passes(self, q: np.ndarray) -> bool:
        """Whether the follow's first step from ``q`` keeps the singularity margins and
        the clearance (every pair measured, as at a follow's start)."""
        return self._first_step_violation(q) is None

    def _first_step_violation(self, q: np.ndarray) -> str | None:
        """What the follow's first step from ``q`` would be blocked by, in its words (the
        singularity margins, then the clearance, every pair measured); None when nothing."""
        limits = self.limits
        singular = singularity_shortfall(abs(math.sin(q[2])), abs(math.sin(q[4])),
                                         abs(shoulder_singularity_distance(q)), limits)
        if singular is not None:
            return singular[1]
        distance, pair, _slack = self._clearance(q.tolist(), np.zeros(len(q)), np.full(len(self._pairs), -np.inf))
        if distance >= limits.clearance_m:
            return None
        robot_id, box_id = pair
        names = self.scene.geometry
        what = "the table" if box_id in self._table_ids else names.describe(box_id)
        return (f"collision with {what}: {names.names.get(robot_id, robot_id)} "
                f"{describe_clearance_shortfall(what, distance, limits.clearance_m)}")

    def why_no_start(self, X_WE: RigidTransform) -> str:
        """Why :meth:`start_candidates` of ``X_WE`` is empty, for a report: no branch
        reaches it, or what blocks the preferred branch (the first the inverse
        kinematics ranks)."""
        branches = self.branches(X_WE)
        if not branches:
            return "no inverse-kinematics solution reaches it"
        best = branches[0]
        if not best.collision_free or best.min_distance_m < self.limits.clearance_m:
            box = best.closest_box or "an obstacle"
            return (f"on its preferred branch, {best.closest_robot_geometry} "
                    f"{describe_clearance_shortfall(box, best.min_distance_m, self.limits.clearance_m)}")
        return f"on its preferred branch, {self._first_step_violation(best.q)}"

    def follow_from_candidates(self, plan: TimedPlan, starts: Sequence[np.ndarray], *,
                               max_starts: int = 3, path_constraints: Sequence = ()) -> JointPath:
        """The first executable path over the first ``max_starts`` start candidates and
        their windings, else the path of the first candidate (its blocker says why);
        ``path_constraints`` as :meth:`follow`'s.

        A plan sharing a prefix with one followed before (the lazy search's next
        composition, the previous trial's plan) resumes where they part
        (:meth:`follow`).
        """
        first = None
        for index, q_start in enumerate(starts[:max_starts]):
            tried = []
            q0 = np.array(q_start, dtype=float)
            for _ in range(3):
                tried.append(q0)
                path = dataclasses.replace(self.follow(plan, q0, path_constraints=path_constraints), start_index=index)
                if first is None:
                    first = path
                if path.executable:
                    return path
                q_next = self._rewound(path, q0)
                if q_next is None or any(np.allclose(q_next, t) for t in tried):
                    break
                q0 = q_next
        return first

    def _rewound(self, path: JointPath, q0: np.ndarray) -> np.ndarray | None:
        """The start turned by 2 pi on a joint whose limit blocked the path, away from
        that limit, when that stays inside the limits; else None."""
        blocker = path.blocker
        if blocker is None or blocker.reason != "joint_limit":
            return None
        q_end = path.q[-1]
        margin_low, margin_high = q_end - self._lower, self._upper - q_end
        j = int(np.argmin(np.minimum(margin_low, margin_high)))
        turn = -2 * math.pi if margin_high[j] < margin_low[j] else 2 * math.pi
        q_new = np.array(q0, dtype=float)
        q_new[j] += turn
        if q_new[j] < self._lower[j] or q_new[j] > self._upper[j]:
            return None
        return q_new

"""A plan on the simulation clock, and replanning when the task changes during a run.

:class:`ScheduledPlan` is what the planner system hands the trajectory source: a
:class:`~drake_lfd.planning.planner.PlanResult`, the simulation time its motion starts
and the pose trajectory to follow (built once). :func:`replan` makes a new
ScheduledPlan when the task changes while the robot moves, following the paper's MDP:
the state is the configuration the robot is in plus the critical configurations still
ahead, so only those are planned again.

- If the critical configuration the robot is heading to did not change (those already
  passed do not matter), the current span is finished as planned and the new plan
  starts there, from rest. Where the current plan stops at that configuration (the
  task's ``stop``, a corner) the join is smooth, velocity zero on both sides; where it
  passes it at speed, the commanded velocity drops to zero there in one step.
- Otherwise the new plan starts from the pose the robot is commanded to at the moment
  of the change (a fixed configuration), through the changed critical configurations
  ahead. The commanded pose is continuous and the new plan starts from rest, so the
  commanded velocity drops to zero at the change.

In both cases the controller's speed and acceleration handling takes up the drop (the
joints never exceed their speed limits: ``tests/test_pipeline.py``); a replan that
continues at speed would need a timing that starts moving, which the plan-time check's
geometric pass (from rest) does not give.

Not for: the Drake system that calls this (``systems/planner.py``) or timing laws.
"""

from __future__ import annotations

import dataclasses
import hashlib
from typing import Callable, Mapping

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.trajectories import PiecewisePose, Trajectory

from drake_lfd.core.features import Feature
from drake_lfd.core.tasks import ConcreteCriticalConfiguration, ConcreteTask
from drake_lfd.core.timing import TimedPlan
from drake_lfd.planning.planner import PlanResult

__all__ = ["ScheduledPlan", "task_fingerprint", "replan", "splice_timed_plans", "constraints_from"]

# Two critical configurations closer than this (m, rad) are the same.
_SAME_CON_TOLERANCE = 1e-9


@dataclasses.dataclass(frozen=True, eq=False)
class ScheduledPlan:
    """A plan (or a demonstration request) on the simulation clock.

    Attributes
    ----------
    result : PlanResult
        What was planned; ``result.timed`` is the motion, time 0 at ``start_time_s``.
    start_time_s : float
        Simulation time of the plan's time 0.
    task_fingerprint : bytes
        Of the task it was planned for (see :func:`task_fingerprint`).
    library_revision : int
        Of the library it was planned with.
    revision : int
        0 for the first plan, +1 for each replan.
    rejected : PlanResult or None
        A replan that failed (for example a demonstration request); the motion then
        carries on with the previous plan.
    inputs : tuple
        The input objects it was planned from (held, so a planner system can tell by
        identity, cheaply, that nothing changed).
    """

    result: PlanResult
    start_time_s: float = 0.0
    task_fingerprint: bytes = b""
    library_revision: int = 0
    revision: int = 0
    rejected: PlanResult | None = None
    inputs: tuple = ()
    # Set by __post_init__ and _built, not arguments: the pose trajectory and its
    # derivative, and the plan's duration.
    _trajectory: PiecewisePose | None = dataclasses.field(default=None, init=False, repr=False, compare=False)
    _velocity: Trajectory | None = dataclasses.field(default=None, init=False, repr=False, compare=False)
    _duration_s: float = dataclasses.field(default=0.0, init=False, repr=False, compare=False)

    def __post_init__(self):
        # The pose trajectory and its derivative are built when first asked for (a cost
        # per plan the compiled closed loop, which tracks the joint path, never asks for).
        object.__setattr__(self, "_trajectory", None)
        object.__setattr__(self, "_velocity", None)
        # Evaluated every control period: plain floats, no array indexing.
        timed = self.result.timed
        object.__setattr__(self, "_duration_s", 0.0 if timed is None else float(timed.times[-1]))

    def __deepcopy__(self, memo):
        return self  # immutable: Drake's copies of a Context share it

    @property
    def planned(self) -> bool:
        return self.result.planned

    @property
    def timed(self) -> TimedPlan | None:
        return self.result.timed

    @property
    def trajectory(self) -> PiecewisePose | None:
        """The pose trajectory of E in W over plan time (None for a request)."""
        return self._built()[0]

    def _built(self) -> tuple[PiecewisePose | None, Trajectory | None]:
        """The pose trajectory and its derivative, built on first use (both None for a
        request)."""
        if self._trajectory is None and self.result.timed is not None:
            trajectory = self.result.timed.to_piecewise_pose()
            object.__setattr__(self, "_trajectory", trajectory)
            object.__setattr__(self, "_velocity", trajectory.MakeDerivative())
        return self._trajectory, self._velocity

    @property
    def end_time_s(self) -> float:
        return self.start_time_s + (self.timed.duration if self.timed is not None else 0.0)

    def due_times_s(self) -> np.ndarray:
        """Simulation times at which each critical configuration is due, shape (n,)."""
        if self.timed is None:
            return np.zeros(0)
        return self.start_time_s + self.timed.times[list(self.timed.critical_indices)]

    def plan_time(self, t: float) -> float:
        """The plan's time at simulation time ``t``, clamped to ``[0, duration]``."""
        return min(max(t - self.start_time_s, 0.0), self._duration_s)

    def X_WE_desired(self, t: float) -> RigidTransform:
        """Desired pose of E at simulation time ``t`` (held before and after the plan)."""
        trajectory = self.trajectory
        assert trajectory is not None  # asked of a plan, not of a demonstration request
        return trajectory.GetPose(self.plan_time(t))

    def V_WE_desired(self, t: float) -> np.ndarray:
        """Desired spatial velocity ``[omega, v]`` of E at ``t``, shape (6,); zero
        outside the plan."""
        tau = t - self.start_time_s
        if tau <= 0.0 or tau >= self._duration_s:
            return np.zeros(6)
        velocity = self._built()[1]
        assert velocity is not None  # a plan (its duration is positive), not a request
        return velocity.value(tau)[:, 0]


def task_fingerprint(task: ConcreteTask) -> bytes:
    """A digest of what the planner reads from a concrete task: positions, angle bounds
    and grids of every critical configuration, base and tool frames. Two tasks with the
    same fingerprint give the same plan."""
    digest = hashlib.sha256()
    for con in task.critical_configurations:
        for values in (con.p, con.euler_zyx_lower, con.euler_zyx_upper):
            digest.update(np.ascontiguousarray(values, dtype=float).tobytes())
        digest.update(repr(float(con.angle_grid_deg)).encode())
    for X in (task.X_WB, task.X_tool0_E):
        digest.update(np.ascontiguousarray(X.GetAsMatrix4(), dtype=float).tobytes())
    for box in tuple(task.obstacles) + tuple(task.safety_shells):
        digest.update(np.ascontiguousarray([*box.centre, *box.size, *box.rotation.ravel()], dtype=float).tobytes())
    return digest.digest()


def _same_con(a: ConcreteCriticalConfiguration, b: ConcreteCriticalConfiguration) -> bool:
    return all(
        np.allclose(x, y, rtol=0.0, atol=_SAME_CON_TOLERANCE)
        for x, y in ((a.p, b.p), (a.euler_zyx_lower, b.euler_zyx_lower), (a.euler_zyx_upper, b.euler_zyx_upper))
    ) and a.angle_grid_deg == b.angle_grid_deg


def splice_timed_plans(first: TimedPlan, cut_time_s: float, second: TimedPlan, *,
                       first_critical_kept: int) -> TimedPlan:
    """``first`` up to its time ``cut_time_s``, then ``second`` (which starts at the pose
    ``first`` has there, at rest), as one TimedPlan.

    The result's critical indices are the first ``first_critical_kept`` critical indices
    of ``first`` (all at or before the cut) and those of ``second``; ``second``'s start
    is a critical configuration only when the cut falls on the last kept one (they
    merge), otherwise it is a plain sample.
    """
    times, poses = np.asarray(first.times), np.asarray(first.poses)
    kept_critical = list(first.critical_indices[:first_critical_kept])
    at_critical = bool(kept_critical) and times[kept_critical[-1]] >= cut_time_s - 1e-9
    if at_critical:
        head = kept_critical.pop()  # second's start is this critical configuration
        cut_time_s = float(times[head])
    else:
        head = int(np.searchsorted(times, cut_time_s - 1e-9, side="left"))
    second_critical = [head + i for i in second.critical_indices]
    if not at_critical:
        second_critical = second_critical[1:]
    return TimedPlan(
        np.concatenate([times[:head], cut_time_s + np.asarray(second.times)]),
        np.concatenate([poses[:head], np.asarray(second.poses)]),
        tuple(kept_critical) + tuple(second_critical),
    )


def _fixed_con_at(X_WE: RigidTransform, grid_deg: float) -> ConcreteCriticalConfiguration:
    rpy = RollPitchYaw(X_WE.rotation())
    euler_zyx = np.array([rpy.yaw_angle(), rpy.pitch_angle(), rpy.roll_angle()])
    con = ConcreteCriticalConfiguration.fixed(X_WE.translation(), euler_zyx)
    return dataclasses.replace(con, angle_grid_deg=grid_deg)


def replan(
    current: ScheduledPlan,
    new_task: ConcreteTask,
    features: Mapping[str, Feature],
    time_s: float,
    plan: Callable[[ConcreteTask], PlanResult],
    *,
    task_digest: bytes,
    library_revision: int,
) -> ScheduledPlan:
    """The plan to follow from ``time_s`` on, for a task that changed to ``new_task``.

    ``plan(task)`` plans a concrete task (the planner system's settings). See the module
    docstring for where the new plan starts. When the new remainder cannot be planned
    (no composition), the current motion is kept and the failed result is returned in
    ``rejected``. Critical configurations already passed do not matter any more.

    Raises
    ------
    ValueError
        When the new task has another number of critical configurations.
    """
    old = current.result
    if not old.planned:
        result = plan(new_task)
        return ScheduledPlan(result, time_s, task_digest, library_revision, current.revision + 1)
    assert old.timed is not None  # a plan has its motion
    cons_old, cons_new = old.task.critical_configurations, new_task.critical_configurations
    n = len(cons_new)
    if len(cons_old) != n:
        raise ValueError(
            f"the task changed from {len(cons_old)} to {n} critical configurations during a run; "
            "replanning keeps their number")
    due = current.due_times_s()
    passed = max(1, int(np.sum(due <= time_s + 1e-9)))  # during settling the robot is at con_1
    if passed >= n:
        return dataclasses.replace(current, task_fingerprint=task_digest, library_revision=library_revision)
    heading = passed  # 0-based index of the critical configuration the robot is heading to
    unchanged = _same_con(cons_old[heading], cons_new[heading])
    grid = cons_new[heading].angle_grid_deg
    if unchanged:
        # Finish the current span; plan from con_(heading+1) at the angles chosen for it.
        start = ConcreteCriticalConfiguration.fixed(cons_old[heading].p, old.euler_zyx[heading])
        start = dataclasses.replace(start, angle_grid_deg=grid)
        cut_time = float(due[heading]) - current.start_time_s
        kept = heading + 1
        remainder = (start,) + tuple(cons_new[heading + 1:])
    else:
        cut_time = current.plan_time(time_s)
        trajectory = current.trajectory
        assert trajectory is not None  # as old.timed
        start = _fixed_con_at(trajectory.GetPose(cut_time), grid)
        kept = heading
        remainder = (start,) + tuple(cons_new[heading:])
    # The sub-task's con numbers start at the configuration it starts from.
    sub_task = dataclasses.replace(new_task, critical_configurations=remainder,
                                   path_constraints=constraints_from(new_task.path_constraints, kept))
    sub = plan(sub_task)
    if not sub.planned:
        return dataclasses.replace(current, task_fingerprint=task_digest, library_revision=library_revision,
                                   rejected=sub)
    assert sub.timed is not None  # planned
    timed = splice_timed_plans(old.timed, cut_time, sub.timed, first_critical_kept=kept)
    # The sub-plan's con numbers shift by the configurations kept from the old plan.
    shift = kept - 1
    kept_steps = tuple(step for step in old.composition if step.con_to <= kept)
    new_steps = tuple(
        dataclasses.replace(step, con_from=step.con_from + shift, con_to=step.con_to + shift)
        for step in sub.composition
    )
    euler = np.array(old.euler_zyx, dtype=float).copy()
    euler[kept - 1 if unchanged else kept:] = sub.euler_zyx[0 if unchanged else 1:]
    result = dataclasses.replace(
        old,
        task=new_task,
        euler_zyx=euler,
        composition=kept_steps + new_steps,
        total_cost=float(sum(step.cost for step in kept_steps + new_steps)),
        timed=timed,
        max_correction_position_m=max(old.max_correction_position_m, sub.max_correction_position_m),
        max_correction_rotation_rad=max(old.max_correction_rotation_rad, sub.max_correction_rotation_rad),
    )
    return ScheduledPlan(result, current.start_time_s, task_digest, library_revision, current.revision + 1)


def constraints_from(path_constraints, first: int) -> tuple:
    """``path_constraints`` renumbered for a sub-task whose con_1 is the old con ``first``
    (1-based) or a pose just before it: con ``c`` becomes ``c - first + 1`` (at least 1); a
    constraint that ends at or before the sub-task's con_1 is gone."""
    shift = first - 1
    return tuple(dataclasses.replace(c, con_from=max(1, c.con_from - shift), con_to=c.con_to - shift)
                 for c in path_constraints if c.con_to - shift > 1)


"""From a concrete task and a library to an SE(3) motion plan or a demonstration request.

Ties the method together (Algorithm 2 and Section 3.4): build the composition problem
(legal actions from similarity), choose a composition with the exact planner or the
Q-policy, map each chosen demonstration onto its span (Eq. 22-25 plus the exact
correction), join the spans, and attach times (``timing.py``). Joins are continuous in
pose; the timing law brings the tool to rest at every critical configuration, so velocity
is continuous too (zero at joins). When no composition exists, report every uncovered
segment and the relative motion it needs (docs/method.rst, Planning).

Not for: reading files (``tasks.py``, ``library.py``) or running the robot.
"""

from __future__ import annotations

import dataclasses
from typing import Callable, Mapping

import numpy as np

from drake_lfd.planning.composition import CompositionProblem, Step
from drake_lfd.core.dual_quaternion import dual_quaternion_relative, translation_from_dual_quaternion
from drake_lfd.core.pose_conversions import dual_quaternion_from_euler_zyx
from drake_lfd.core.quaternion import axis_angle_from_quaternion
from drake_lfd.planning.exact_planner import plan_exact
from drake_lfd.planning.executable import InfeasibleSegment, search_executable
from drake_lfd.planning.problem_size import check_problem_size
from drake_lfd.planning.options import PLANNERS, PlanningOptions
from drake_lfd.planning.refusals import PoseBlockers, blocked_configurations, distinct_reasons
from drake_lfd.planning.stretching import solve_within_stretch_bound
from drake_lfd.core.exact_memo import ExactMemo, exact_key
from drake_lfd.core.features import Feature
from drake_lfd.core.fidelity import FidelityWeights, check_cost_mode
from drake_lfd.core.mapping import least_anchor_correction_m, map_segment, map_segment_twists
from drake_lfd.planning.q_learning import QPolicy, plan_q
from drake_lfd.core.similarity import Tolerances
from drake_lfd.core.tasks import Box, ConcreteTask, angle_candidates, stops_of
from drake_lfd.robot.analytic_ik import UR5E_DH_D
from drake_lfd.robot.clearance import LINK_RADIUS_M, clearances, tool_clearance_points
from drake_lfd.robot.dh_kinematics import ur5e_reach_m
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.joint_path_records import JointPath
from drake_lfd.robot.path_timing import TimingError, retime_plan
from drake_lfd.core.timing import TimedPlan, TimingLimits, time_plan

__all__ = [
    'PLANNERS',
    'ComposedStep',
    'UncoveredSegment',
    'PlanResult',
    'task_candidates',
    'build_problem',
    'uncovered_segments',
    'TWIST_CANDIDATES_RAD',
    'CLEARANCE_GOAL_M',
    'twist_order',
    'map_span_clear',
    'compose_plan',
    'out_of_reach',
    'plan_composition',
]



@dataclasses.dataclass(frozen=True)
class ComposedStep:
    """One step of a plan; ``max_correction_*``: the largest correction its mapping made
    on its span (``planning/stretching.py`` bounds the position's)."""

    demo: str
    con_from: int  # 1-based
    con_to: int  # 1-based
    cost: float
    max_correction_position_m: float = 0.0
    max_correction_rotation_rad: float = 0.0


@dataclasses.dataclass(frozen=True)
class UncoveredSegment:
    """A segment no demonstration covers, and the relative motion ``D_from* (x) D_to``
    it needs, expressed in con_from's frame."""

    con_from: int  # 1-based
    con_to: int
    axis: np.ndarray  # (3,)
    angle_rad: float
    translation_m: np.ndarray  # (3,)
    pose_from: np.ndarray | None = None  # (8,) X_WE of con_from (the candidate used)
    pose_to: np.ndarray | None = None  # (8,) X_WE of con_to


@dataclasses.dataclass(frozen=True, eq=False)
class PlanResult:
    """Outcome of planning one concrete task.

    ``status`` is ``"planned"``, ``"demonstration_requested"`` or, when planned with a
    joint-space checker, ``"no_executable_plan"`` (demonstrations cover the task but
    every composition is blocked for the robot: ``infeasible`` says where and why). For a
    plan, ``euler_zyx`` (n, 3) holds the concrete angles chosen for every con, ``timed``
    the timed SE(3) poses of E in W and ``joint_path`` (with a checker) the joint path
    the controller will command; ``infeasible`` then lists the compositions' segments
    found blocked on the way. ``greedy_completed`` / ``fallback`` describe the Q-planner
    (``fallback`` is ``"exact"`` when the greedy walk dead-ended).
    """

    status: str
    planner: str
    task: ConcreteTask
    euler_zyx: np.ndarray
    composition: tuple[ComposedStep, ...] = ()
    total_cost: float = float("nan")
    timed: TimedPlan | None = None
    max_correction_position_m: float = 0.0
    max_correction_rotation_rad: float = 0.0
    uncovered: tuple[UncoveredSegment, ...] = ()
    greedy_completed: bool | None = None
    fallback: str | None = None
    refine_episodes: int = 0
    joint_path: JointPath | None = None
    infeasible: tuple[InfeasibleSegment, ...] = ()
    search_rounds: int = 0
    refinement: object | None = None  # planning/refinement.RefinementReport, with --refine
    timing: str = "geometric"  # "time_optimal" when timed along the checked joint path

    @property
    def planned(self) -> bool:
        return self.status == "planned"


def task_candidates(task: ConcreteTask) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Candidate angles (g_j, 3) and poses (g_j, 8) of every critical configuration."""
    angles = [angle_candidates(con) for con in task.critical_configurations]
    poses = [
        dual_quaternion_from_euler_zyx(np.broadcast_to(con.p, a.shape), a)
        for con, a in zip(task.critical_configurations, angles)
    ]
    return angles, poses


def build_problem(
    task: ConcreteTask,
    features: Mapping[str, Feature],
    tolerances: Tolerances = Tolerances(),
    max_span: int | None = None,
    cost: str = "paper",
    fidelity_weights: FidelityWeights = FidelityWeights(),
) -> CompositionProblem:
    """The :class:`CompositionProblem` of a concrete task, in cost mode ``cost``
    (``"paper"``: Eq. 31; ``"fidelity"``: plus the shape-fidelity terms)."""
    check_cost_mode(cost)
    check_problem_size(task, features, max_span, cost)  # before anything is allocated
    _, poses = task_candidates(task)
    return CompositionProblem(poses, list(features.values()), tolerances, max_span, cost, fidelity_weights)


def uncovered_segments(problem: CompositionProblem) -> list[UncoveredSegment]:
    """Segments to ask a demonstration for, when no composition covers the task.

    Every gap con_g -> con_(g+1) that no legal action spans is reported. If every gap is
    spanned by something but the spans do not chain (their angle choices disagree), the
    gap after the furthest critical configuration reachable from con_1 is reported.
    Bounded angles take the reachable candidate (or the middle of their grid).
    """
    covered = problem.covered_gaps()
    reachable = _reachable_candidates(problem)
    gaps = [g for g in range(problem.num_cons - 1) if not covered[g]]
    if not gaps:
        furthest = max(j for j in range(problem.num_cons) if reachable[j])
        gaps = [min(furthest, problem.num_cons - 2)]
    segments = []
    for g in gaps:
        from_candidates = reachable[g] or [problem.num_candidates[g] // 2]
        D_from = problem.candidate_poses[g][from_candidates[0]]
        D_to = problem.candidate_poses[g + 1][problem.num_candidates[g + 1] // 2]
        relative = dual_quaternion_relative(D_from, D_to)
        axis, angle = axis_angle_from_quaternion(relative[:4])
        segments.append(
            UncoveredSegment(g + 1, g + 2, axis, float(angle), translation_from_dual_quaternion(relative),
                             np.array(D_from, dtype=float), np.array(D_to, dtype=float))
        )
    return segments


def _reachable_candidates(problem: CompositionProblem) -> list[list[int]]:
    reachable: list[set[int]] = [set() for _ in range(problem.num_cons)]
    reachable[0] = set(range(problem.num_candidates[0]))
    for j in range(problem.num_cons - 1):
        for a in sorted(reachable[j]):
            for step in problem.actions_from(j, a):
                reachable[step.k].add(step.a_k)
    return [sorted(r) for r in reachable]


TWIST_CANDIDATES_RAD = np.radians(np.arange(0.0, 360.0, 30.0))
# The executable-plan search tries, for a blocked step, this many demo suffixes times
# this many twists (best first) before it forbids the step.
SUFFIX_ALTERNATIVES = 2
TWIST_ALTERNATIVES = 3
# A mapped path this far from every keep-out box is clear; among clear twists the one
# closest to the paper's shortest alignment (twist 0) is kept.
CLEARANCE_GOAL_M = 0.05 + LINK_RADIUS_M


def twist_order(feature_poses, allocation, task_poses, keep_out=(), floor_z=None, points_E=None,
                limit: int | None = None) -> list[float]:
    """The free twists of a span (30 deg steps about the task's first translation,
    docs/method.rst, Mapping), best first: by the mapped path's total shortfall below
    ``CLEARANCE_GOAL_M`` from the keep-out boxes and the floor (summed over samples and
    tracked points, so a critical configuration that itself touches a shell does not
    hide the rest of the path), rounded to a micrometre so floating-point noise (a rigid
    motion of the whole task) cannot decide between equally clear twists; then the
    smaller turn, then the positive one. Twist 0, the paper's shortest alignment, comes
    first when its path is clear (the others are then not scored unless ``limit`` asks
    for more than one). Without boxes or floor: ``[0.0]``.
    """
    if not keep_out and floor_z is None:
        return [0.0]

    def shortfalls(poses: np.ndarray) -> list[float]:
        """Each path's (a, N, 8) total shortfall below the clearance goal, rounded."""
        distance = clearances(poses.reshape(-1, 8), keep_out, floor_z, points_E).reshape(len(poses), -1)
        return [round(float(np.sum(np.maximum(CLEARANCE_GOAL_M - row, 0.0))), 6) for row in distance]

    twists = TWIST_CANDIDATES_RAD
    if limit is None or limit <= 1:  # twist 0 alone, when its path is clear
        first = shortfalls(map_segment(feature_poses, allocation, task_poses, twist_rad=0.0).poses[None])[0]
        if first == 0.0:
            return [0.0]
    # Every twist at once: the same poses as one mapping per twist (map_segment_twists).
    scored = [(shortfall, round(float(min(twist, 2 * np.pi - twist)), 9), order, float(twist))
              for order, (twist, shortfall) in enumerate(zip(
                  twists, shortfalls(map_segment_twists(feature_poses, allocation, task_poses, twists))))]
    scored.sort()
    twists = [twist for *_, twist in scored]
    return twists if limit is None else twists[:limit]



def _clearance_scene_key(keep_out, floor_z) -> tuple:
    """What :func:`twist_order` reads of the boxes and the floor, exactly."""
    boxes = tuple(exact_key(box.centre, box.size, box.rotation) for box in keep_out)
    floor = exact_key(floor_z.centre, floor_z.size, floor_z.rotation) if isinstance(floor_z, Box) else floor_z
    return boxes, floor


def map_span_clear(feature_poses, allocation, task_poses, keep_out=(), floor_z=None, points_E=None,
                   twist: float | None = None):
    """Maps a demo onto a span with the best free twist of :func:`twist_order` (or the
    given ``twist``), keeping the tool path clear of the keep-out boxes and the floor.
    Returns the MappedSegment and the twist."""
    if twist is None:
        twist = twist_order(feature_poses, allocation, task_poses, keep_out, floor_z, points_E, limit=1)[0]
    return map_segment(feature_poses, allocation, task_poses, twist_rad=float(twist)), float(twist)


def compose_plan(
    problem: CompositionProblem,
    steps: list[Step],
    features: Mapping[str, Feature],
    angles: list[np.ndarray],
    keep_out=(),
    floor_z: float | None = None,
    points_E: np.ndarray | None = None,
    overrides: Mapping[int, tuple[int | None, float | None]] | None = None,
    per_step: list | None = None,
    mapping: Callable | None = None,
) -> tuple[np.ndarray, list[int], np.ndarray, list[float], float, float]:
    """Maps each step's demo onto its span (see :func:`map_span_clear`) and joins them.

    ``overrides[i] = (first_index, twist)`` maps step ``i`` from another demo suffix
    (:meth:`CompositionProblem.suffix_candidates`) and/or with another twist (None: the
    default choice), for the executable-plan search.

    Returns poses (N, 8), critical indices (n,), chosen euler_zyx (n, 3), the exact
    cost of each step (its allocation's total alpha), and the largest position and
    rotation corrections applied; ``per_step``, when given, receives each step's
    ``(position_m, rotation_rad)`` corrections. ``mapping(step, first_index, twist)``,
    when given, returns a step's allocation and mapping in place of computing them (the
    search keeps them, as it composes the same steps again and again).
    """
    names = list(features)
    n = problem.num_cons
    chosen = np.zeros((n, 3))
    chosen[0] = angles[0][steps[0].a_j]
    pieces: list[np.ndarray]
    pieces, critical, costs = [], [0], []
    max_position, max_rotation = 0.0, 0.0
    overrides = overrides or {}

    def map_step(step, first_index, twist):
        span = problem.span_allocation(step, first_index)
        task_poses = np.array([problem.candidate_poses[step.j + o][c] for o, c in enumerate(span.candidates)])
        feature = features[names[step.demo]]
        mapped, _twist = map_span_clear(feature.poses, span.allocation, task_poses, keep_out, floor_z, points_E,
                                        twist=twist)
        return span, mapped

    for index, step in enumerate(steps):
        first_index, twist = overrides.get(index, (None, None))
        span, mapped = (mapping or map_step)(step, first_index, twist)
        costs.append(span.allocation.cost)
        for offset, candidate in enumerate(span.candidates):
            chosen[step.j + offset] = angles[step.j + offset][candidate]
        start = sum(len(p) for p in pieces) - (1 if pieces else 0)
        pieces.append(mapped.poses if not pieces else mapped.poses[1:])
        anchors = np.asarray(mapped.anchor_indices)
        critical.extend(int(start + a) for a in anchors[1:])
        max_position = max(max_position, mapped.max_correction_position_m)
        max_rotation = max(max_rotation, mapped.max_correction_rotation_rad)
        if per_step is not None:
            per_step.append((mapped.max_correction_position_m, mapped.max_correction_rotation_rad))
    return np.concatenate(pieces), critical, chosen, costs, max_position, max_rotation


def out_of_reach(task: ConcreteTask) -> list[InfeasibleSegment]:
    """The critical configurations farther from the shoulder than the arm can reach
    (:func:`~drake_lfd.robot.dh_kinematics.ur5e_reach_m`), one segment each (the one
    arriving at it; con_1 -> con_2 for con_1)."""
    shoulder = task.X_WB.multiply(np.array([0.0, 0.0, UR5E_DH_D[0]]))  # (d1: the shoulder above the base)
    reach = ur5e_reach_m(task.X_tool0_E)
    segments = []
    n = len(task.critical_configurations)
    for i, con in enumerate(task.critical_configurations):
        distance = float(np.linalg.norm(np.asarray(con.p, dtype=float) - shoulder))
        if not distance <= reach:
            number = i + 1
            segments.append(InfeasibleSegment(
                max(number - 1, 1), min(max(number, 2), n), "reach",
                f"con_{number} at p = {np.round(np.asarray(con.p, dtype=float), 3).tolist()} m is "
                f"{distance:.3g} m from the shoulder; the UR5e with this tool reaches {reach:.2f} m"))
    return segments


def plan_composition(
    task: ConcreteTask,
    features: Mapping[str, Feature],
    options: PlanningOptions,
    *,
    policy: QPolicy | None = None,
    seed: int = 0,
    floor_z: float | None = None,
    checker: JointPathChecker | None = None,
    clearance_points_E: np.ndarray | None = None,
) -> PlanResult:
    """Plans one concrete task with the library's ``features`` as ``options`` say: the
    core of :func:`drake_lfd.plan_task`, which also resolves the library, builds the
    checker and refines.

    ``options.planner`` is ``"exact"`` or ``"q"`` (the Q-planner, with ``policy``, first
    refines on the task for ``options.refine_episodes`` episodes, seeded by ``seed``).
    ``options.cost`` is the action cost both planners minimise: ``"paper"``, Eq. 31's
    total alpha (the shape-fidelity terms only break its ties), or ``"fidelity"``, alpha
    plus the shape-fidelity terms weighted by ``options.fidelity_weights``
    (``core/fidelity.py``, docs/method.rst, Shape fidelity). The plan's ``total_cost``
    and step costs are the chosen allocations' total alpha (Eq. 31) in both modes.
    ``options.joint_check`` and ``options.refine`` are for the caller that builds the
    checker and refines (:func:`drake_lfd.plan_task`, the planner system): here the
    ``checker`` given decides.

    With a ``checker`` (the task's scene and the controller's law), only executable
    compositions are returned (``planning/executable.py``): a critical configuration
    out of reach, or every covering composition blocked, gives ``no_executable_plan``.
    The executable plan is then timed time-optimally along its checked joint path under
    ``options.timing`` (default: the task's ``timing`` block, else
    :class:`TimingLimits`'s defaults; ``robot/path_timing.py``), stopping where the
    task's critical configurations say ``stop`` (the first and the last by default) and
    at corners. Without a checker the plan keeps the geometric pass's timing
    (``core/timing.py``, with ``options.max_speed_m_s`` and
    ``options.max_angular_speed_rad_s``).

    Each span's free twist keeps the tool path clear of the task's obstacles and shells
    and above ``floor_z``; ``clearance_points_E`` (k, 3) are the points fixed in E that
    must stay clear (default: :func:`~drake_lfd.robot.clearance.tool_clearance_points` of the task's ``X_tool0_E``).
    """
    if not isinstance(options, PlanningOptions):
        raise TypeError(f"options must be PlanningOptions, got {type(options).__name__}")
    planner, cost = options.planner, options.cost
    tolerances, max_span, fidelity_weights = options.tolerances, options.max_span, options.fidelity_weights
    refine_episodes, timing = options.refine_episodes, options.timing
    max_speed_m_s, max_angular_speed_rad_s = options.max_speed_m_s, options.max_angular_speed_rad_s
    if planner == "q" and policy is None:
        raise ValueError("the q planner needs a policy")
    check_problem_size(task, features, max_span, cost)  # before anything is allocated
    angles, poses = task_candidates(task)
    nominal = np.array([a[len(a) // 2] for a in angles])
    refined = refine_episodes if planner == "q" else 0
    if checker is not None:
        unreachable = out_of_reach(task)
        if unreachable:
            return PlanResult("no_executable_plan", planner, task, nominal, infeasible=tuple(unreachable),
                              refine_episodes=refined)
    problem = CompositionProblem(poses, list(features.values()), tolerances, max_span, cost, fidelity_weights)
    q_outcome: dict = {}

    def solve(problem: CompositionProblem):
        if planner == "exact":
            return plan_exact(problem)
        assert policy is not None  # the q planner was refused above without one
        q_plan = plan_q(problem, policy, refine_episodes=refine_episodes, seed=seed)
        q_outcome.update(greedy_completed=q_plan.greedy_completed, fallback=q_plan.fallback)
        return q_plan.steps

    keep_out = tuple(task.obstacles) + tuple(task.safety_shells)
    points_E = tool_clearance_points(task.X_tool0_E) if clearance_points_E is None else clearance_points_E

    feature_list = list(features.values())
    scene_key = _clearance_scene_key(keep_out, floor_z)
    # With a checker (built once per scene), the twist orders of earlier plans in it by
    # their exact inputs: trials of a task whose spans do not depend on its variables
    # (filling and pouring's first two) order their twists once.
    scene_twists = ExactMemo(maxsize=1) if checker is None else checker.twist_orders
    span_memo: dict = {}
    twist_memo: dict = {}
    mapped_memo: dict = {}

    def span_poses(step, first):
        """``step``'s allocation from suffix ``first`` and its candidates' task poses
        (memoized: the twists and the stretch bound both need them)."""
        key = (step, first)
        if key not in span_memo:
            span = problem.span_allocation(step, first)
            span_memo[key] = span, np.array(
                [problem.candidate_poses[step.j + o][c] for o, c in enumerate(span.candidates)])
        return span_memo[key]

    def mapped_step(step, first, twist):
        """``step``'s allocation from suffix ``first`` and its mapping with ``twist``
        (memoized: compose, the stretch bound and the search's pose check share them)."""
        key = (step, first, float(twist))
        if key not in mapped_memo:
            span, task_poses = span_poses(step, first)
            mapped_memo[key] = span, map_span_clear(feature_list[step.demo].poses, span.allocation, task_poses,
                                                    keep_out, floor_z, points_E, twist=twist)[0]
        return mapped_memo[key]

    def twists_of(step, first, limit):
        """The twist order of ``step`` mapped from suffix ``first`` (memoized: the search
        composes the same steps again and again)."""
        key = (step, first, limit)
        if key not in twist_memo:
            span, task_poses = span_poses(step, first)
            feature_poses = feature_list[step.demo].poses
            exact = exact_key(feature_poses, np.asarray(span.allocation.indices), task_poses, scene_key, points_E,
                              limit)
            twist_memo[key] = scene_twists.get(exact, lambda: twist_order(
                feature_poses, span.allocation, task_poses, keep_out, floor_z, points_E, limit=limit))
        return twist_memo[key]

    def compose(steps: list[Step], overrides: Mapping[int, tuple[int | None, float | None]] | None = None,
                ) -> tuple[TimedPlan, np.ndarray, list[float], float, float, list[tuple[float, float]]]:
        overrides = dict(overrides or {})
        for index, step in enumerate(steps):
            first, twist = overrides.get(index, (None, None))
            if twist is None:
                overrides[index] = (first, twists_of(step, first, 1)[0])
        per_step: list = []
        path, critical, chosen, costs, max_position, max_rotation = compose_plan(
            problem, steps, features, angles, keep_out, floor_z, points_E, overrides, per_step, mapped_step)
        timed = time_plan(path, critical, max_speed_m_s=max_speed_m_s,
                          max_angular_speed_rad_s=max_angular_speed_rad_s)
        return timed, chosen, costs, max_position, max_rotation, per_step

    correction_memo: dict = {}

    def correction_of(step):
        """The largest position correction of ``step``'s default mapping (memoized)."""
        if step not in correction_memo:
            _, mapped = mapped_step(step, None, twists_of(step, None, 1)[0])
            correction_memo[step] = mapped.max_correction_position_m
        return correction_memo[step]

    # The twists a default mapping may take (twist_order's candidates).
    twists_possible = [0.0] if not keep_out and floor_z is None else TWIST_CANDIDATES_RAD

    least_memo: dict = {}

    def least_correction_of(step):
        """A lower bound on :func:`correction_of` from the anchors alone, whichever twist
        (memoized)."""
        if step in correction_memo:
            return correction_memo[step]
        if step not in least_memo:
            span, task_poses = span_poses(step, None)
            least_memo[step] = least_anchor_correction_m(feature_list[step.demo].poses, span.allocation, task_poses,
                                                         twists_possible)
        return least_memo[step]

    if cost == "fidelity":  # the paper's cost keeps Eq. 31 and its choices as they are
        unbounded_solve = solve

        def solve(problem: CompositionProblem):
            return solve_within_stretch_bound(problem, unbounded_solve, correction_of, least_correction_of)

    def step_poses(step, option):
        """``step`` mapped as ``option`` (suffix, twist; a twist None: the suffix's best,
        as compose takes it): its poses and the indices of its critical configurations."""
        first, twist = option
        _, mapped = mapped_step(step, first, twists_of(step, first, 1)[0] if twist is None else twist)
        return mapped.poses, mapped.anchor_indices

    def alternatives(step):
        """Other demo suffixes and twists for ``step``, best first (the default left out)."""
        options = []
        for first in problem.suffix_candidates(step, SUFFIX_ALTERNATIVES):
            for twist in twists_of(step, first, TWIST_ALTERNATIVES):
                options.append((first, twist))
        return options[1:]  # the first is the default mapping

    names = list(features)
    blocked: tuple[InfeasibleSegment, ...]
    joint_path, blocked, rounds = None, (), 0
    if checker is None:
        steps = solve(problem)
        composed = None if steps is None else compose(steps)
    else:
        search = search_executable(problem, solve, compose, checker, names, alternatives=alternatives,
                                   refusal=lambda problem: blocked_configurations(problem, checker),
                                   path_constraints=task.path_constraints,
                                   pose_blockers=lambda: PoseBlockers(checker), step_poses=step_poses)
        steps, composed, joint_path, blocked, rounds = (
            search.steps, search.composed, search.joint_path, distinct_reasons(search.blocked), search.rounds)
    greedy_completed, fallback = q_outcome.get("greedy_completed"), q_outcome.get("fallback")
    if steps is None:
        if blocked:
            return PlanResult("no_executable_plan", planner, task, nominal, infeasible=blocked,
                              greedy_completed=greedy_completed, fallback=fallback,
                              refine_episodes=refined, search_rounds=rounds)
        return PlanResult(
            "demonstration_requested", planner, task, nominal,
            uncovered=tuple(uncovered_segments(problem)),
            greedy_completed=greedy_completed, fallback=fallback,
            refine_episodes=refined,
        )
    assert composed is not None  # the steps found were composed
    timed, chosen, costs, max_position, max_rotation, per_step = composed
    timing_kind = "geometric"
    if joint_path is not None:
        # The executed timing: time-optimal along the checked joint path (if Toppra finds
        # none, the checked geometric pass stands: slower, at rest at every configuration).
        limits = timing if timing is not None else (task.timing or TimingLimits())
        assert checker is not None  # a joint path comes from the checker's search
        try:
            timed, joint_path, _ = retime_plan(timed, joint_path, stops_of(task), checker.kinematics, limits)
            timing_kind = "time_optimal"
        except TimingError:
            pass
    composition = tuple(
        ComposedStep(names[s.demo], s.j + 1, s.k + 1, cost, *correction)
        for s, cost, correction in zip(steps, costs, per_step)
    )
    return PlanResult(
        "planned", planner, task, chosen, composition, float(sum(costs)), timed,
        max_position, max_rotation, (), greedy_completed, fallback, refined,
        joint_path=joint_path, infeasible=blocked, search_rounds=rounds, timing=timing_kind,
    )

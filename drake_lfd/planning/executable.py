"""Executable compositions: the search keeps only compositions whose joint path passes.

A composition is planned in SE(3); whether the UR5e can run it shows only in joint
space. Checking every legal action's joint path would cost a follow of the controller's
law per action and start state, so the check is lazy, as lazy collision checking in
sampling planners:

1. solve for the best composition and follow its whole joint path from the preferred
   start (:meth:`~drake_lfd.robot.joint_path.JointPathChecker.follow_from_candidates`:
   the first pose's preferred inverse-kinematics branch, with its 2 pi windings);
2. if it is blocked, try the blocked step's other mappings (another suffix of the
   demonstration, another free twist; best first, a few of each) and keep the first
   that gets the arm past the step;
3. if none does, forbid the action (demo, span and candidate angles) and solve again.

Both planners choose only among the actions left, so the composition returned is
executable, or none is and every forbidden action is reported with its reason. Only
when nothing runs from the preferred start does the search start over from the next
branch (at most three).

The follow checks the task's path constraints too (a composition turning the tool too
far is blocked like a collision). Once a follow has been blocked, a composition whose
poses alone show the follow would be blocked (``refusals.PoseBlockers``: a pan sweep
through a shape's blocked pan, a singularity on the start's branch) stands blocked
without being followed, and an alternative mapping whose own poses show it is passed
over before it is composed. A later start, once woken, forbids at once the earlier
starts' steps whose every mapping its poses block, so the planner does not offer them
again one by one.

A span's feasibility depends on the joint state it starts from; forbidding the action
for every start is the approximation that keeps the search small (an action blocked
after one prefix may run after another).

Not for: the joint-space check itself (``robot/joint_path.py``) or building the plan
(``planner.py``).
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from pydrake.math import RigidTransform

from drake_lfd.core.pose_conversions import matrices_from_dual_quaternion
from drake_lfd.planning.composition import CompositionProblem, Step
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.joint_path_records import Blocker, JointPath

if TYPE_CHECKING:  # refusals imports this module
    from drake_lfd.planning.refusals import PoseBlockers

__all__ = ["MAX_SEARCH_ROUNDS", "MAX_START_BRANCHES", "InfeasibleSegment", "ExecutableSearch",
           "search_executable"]

# Solve-check-forbid rounds before giving up (each forbids one action).
MAX_SEARCH_ROUNDS = 40
# Inverse-kinematics branches of the first pose the search starts from, best first.
MAX_START_BRANCHES = 3


@dataclasses.dataclass(frozen=True)
class InfeasibleSegment:
    """A segment of a composition that the robot cannot run, and why.

    ``con_from``/``con_to`` are 1-based; ``reason`` one of ``reach``, ``joint_limit``,
    ``singularity``, ``collision``, ``path_constraint``; ``demo`` the demonstration
    mapped onto it (empty for a critical configuration out of reach before any
    composition); ``blocked_alternatives`` how many alternatives (actions: demo, span
    and candidate angles) this reason blocked."""

    con_from: int
    con_to: int
    reason: str
    detail: str
    demo: str = ""
    blocked_alternatives: int = 1

    def describe(self) -> str:
        demo = f" ({self.demo})" if self.demo else ""
        blocked = f" [blocks {self.blocked_alternatives} alternatives]" if self.blocked_alternatives > 1 else ""
        return f"con_{self.con_from} -> con_{self.con_to}{demo}: {self.reason}: {self.detail}{blocked}"


@dataclasses.dataclass(frozen=True)
class ExecutableSearch:
    """The outcome of :func:`search_executable`.

    ``steps`` and ``composed`` (what ``compose`` returned for them) and ``joint_path``
    are None when nothing executes; ``blocked`` lists the forbidden segments, in the
    order they were found; ``rounds`` counts the compositions checked;
    ``tried_a_start`` is False when no composition had the start branch asked for."""

    steps: list[Step] | None
    composed: tuple | None
    joint_path: JointPath | None
    blocked: tuple[InfeasibleSegment, ...]
    rounds: int
    tried_a_start: bool = True


def _blocking_index(steps: list[Step], blocker: Blocker) -> int:
    """Index of the step whose span holds the blocker (its span index is 0-based, con
    to con)."""
    for index, step in enumerate(steps):
        if step.j <= blocker.span < step.k:
            return index
    return len(steps) - 1


def search_executable(
    problem: CompositionProblem,
    solve: Callable[[CompositionProblem], list[Step] | None],
    compose: Callable[..., tuple],
    checker: JointPathChecker,
    demo_names: list[str],
    *,
    alternatives: Callable[[Step], list] | None = None,
    max_rounds: int = MAX_SEARCH_ROUNDS,
    max_starts: int = MAX_START_BRANCHES,
    refusal: Callable[[CompositionProblem], list[InfeasibleSegment]] | None = None,
    path_constraints: Sequence = (),
    pose_blockers: Callable[[], PoseBlockers] | None = None,
    step_poses: Callable[[Step, tuple], tuple[np.ndarray, Sequence[int]]] | None = None,
) -> ExecutableSearch:
    """Lazy search for an executable composition (see the module docstring).

    ``solve(problem)`` returns the planner's composition or None; ``compose(steps,
    overrides)`` returns a tuple whose first item is the
    :class:`~drake_lfd.core.timing.TimedPlan`, ``overrides`` mapping a step's index to
    its ``(first_index, twist)``; ``alternatives(step)`` lists the other mappings of a
    step (demo suffix and twist) to try, best first, before the step is forbidden.

    The search runs from the preferred start (inverse-kinematics branch) of the first
    pose; only when nothing runs from it does it start over from the next branch, up to
    ``max_starts``, each time on a fresh copy of ``problem`` (an action blocked from one
    start may run from another). The blocked segments reported are the first start's.

    ``refusal(problem)`` (``planning/refusals.py``) is asked once, when the search
    first meets a blocked step or start (before the step's alternatives): the
    segments it returns block every composition whatever is chosen, and the search
    stops with them at once. Asked then rather than before the first
    follow, it costs nothing on a composition that runs at once (the common case);
    asked before the alternatives are followed one by one, a refusal no choice can
    change is not delayed by them. Alternatives forbid nothing, so the problem it sees
    is the one it would see after them, and its segments are the same.

    ``path_constraints`` (the task's) are checked on every follow: a composition that
    turns the tool beyond one is blocked like a collision, and the search tries the
    others (:meth:`~drake_lfd.robot.joint_path.JointPathChecker.follow`).

    ``pose_blockers()`` makes, per start branch, the judge of compositions by their poses
    alone (``planning/refusals.PoseBlockers``): its ``record(plan, path)`` learns from
    each blocked follow and its ``blocker_of(plan, spans)`` returns the blocker a
    composition's poses show, which then stands for its follow (the composition is
    ruled out unfollowed). With ``step_poses(step, mapping)`` (a step's own mapped poses
    and the indices of its critical configurations), an alternative mapping whose own
    poses show a blocker in its spans is passed over before anything is composed: the
    check of the composed plan would find that blocker there.
    """
    first = None
    asked: list = []
    forbidden: list[Step] = []  # steps forbidden on the starts searched so far, in order

    def refused(problem):
        if refusal is not None and not asked:
            asked.append(tuple(refusal(problem)))
        return asked[0] if asked else ()

    for start_index in range(max_starts):
        attempt = copy.copy(problem)
        attempt.cost = dict(problem.cost)
        search = _search_from(attempt, solve, compose, checker, demo_names, start_index,
                              alternatives=alternatives, max_rounds=max_rounds, refused=refused,
                              path_constraints=path_constraints,
                              pose_blockers=None if pose_blockers is None else pose_blockers(),
                              step_poses=step_poses, forbidden=forbidden)
        if search.steps is None and asked and asked[0]:
            return search  # no other start can help
        if search.steps is not None:
            if first is not None:
                search = dataclasses.replace(search, blocked=first.blocked + search.blocked,
                                             rounds=first.rounds + search.rounds)
            return search
        if first is None:
            first = search
        if not search.tried_a_start:
            break  # no composition even had this start branch to try
    assert first is not None  # max_starts >= 1: the first start's search is kept
    return first


def _search_from(problem: CompositionProblem, solve: Callable[[CompositionProblem], list[Step] | None],
                 compose: Callable[..., tuple], checker: JointPathChecker, demo_names: list[str], start_index: int,
                 *, alternatives: Callable[[Step], list] | None, max_rounds: int,
                 refused: Callable[[CompositionProblem], tuple[InfeasibleSegment, ...]] = lambda problem: (),
                 path_constraints: Sequence = (), pose_blockers: PoseBlockers | None = None,
                 step_poses: Callable[[Step, tuple], tuple[np.ndarray, Sequence[int]]] | None = None,
                 forbidden: list[Step] | None = None,
                 ) -> ExecutableSearch:
    """The lazy search with the start fixed to branch ``start_index`` (see
    :func:`search_executable`). ``forbidden``: the steps earlier starts forbade (this
    start's are added)."""
    blocked: list[InfeasibleSegment] = []
    tried_a_start = False
    overrides: dict[Step, tuple] = {}  # mappings adopted for steps, by step
    tried: set[Step] = set()  # steps whose alternatives were tried
    earlier = [] if forbidden is None else list(forbidden)  # what the earlier starts forbade
    rounds = 0
    while rounds < max_rounds:
        if earlier and pose_blockers is not None and pose_blockers.awake and step_poses is not None:
            _forbid_what_poses_block(problem, earlier, pose_blockers, step_poses, alternatives)
            earlier = []
        rounds += 1
        steps = solve(problem)
        if steps is None:
            return ExecutableSearch(None, None, None, tuple(blocked), rounds - 1, tried_a_start)

        def check(current: dict, spans: range | None = None):
            """Composes with the mappings ``current`` and follows it from the start branch
            ``start_index`` (with its windings); None when there is no such branch. A
            composition ``pose_blockers`` rules out in ``spans`` (all by default) is not
            followed: only there does its blocker stand for the follow's (a later span's
            would hide whether the spans before it run)."""
            composed = compose(steps, {i: current[s] for i, s in enumerate(steps) if s in current})
            timed = composed[0]
            starts = checker.start_candidates(RigidTransform(matrices_from_dual_quaternion(timed.poses[:1])[0]))
            if len(starts) <= start_index:
                return composed, None
            blocker = None if pose_blockers is None else pose_blockers.blocker_of(timed, spans)
            if blocker is not None:
                return composed, JointPath(np.array([blocker.time_s]), np.zeros((0, 6)), blocker, (), math.inf,
                                           math.inf, math.inf, math.inf, start_index=start_index)
            path = checker.follow_from_candidates(timed, starts[start_index:start_index + 1],
                                                  path_constraints=path_constraints)
            if pose_blockers is not None and not path.executable:
                pose_blockers.record(timed, path)
            return composed, dataclasses.replace(path, start_index=start_index)

        composed, path = check(overrides)
        if path is not None:
            tried_a_start = True
        if path is None:
            # con_1 at this candidate has no joint configuration a follow can start
            # from (on this start's branch): no action from it can run.
            refusal = refused(problem)
            if refusal:
                return ExecutableSearch(None, None, None, refusal, rounds, tried_a_start)
            step = steps[0]
            if start_index == 0:
                X_WE = RigidTransform(matrices_from_dual_quaternion(composed[0].poses[:1])[0])
                detail = (f"no joint configuration a follow can start from reaches con_{step.j + 1} "
                          f"({checker.why_no_start(X_WE)})")
            else:
                detail = f"con_{step.j + 1} has no start branch {start_index + 1}"
            blocked.append(InfeasibleSegment(step.j + 1, step.k + 1, "reach", detail, demo_names[step.demo]))
            problem.forbid_state(step.j, step.a_j)
            continue
        if path.executable:
            return ExecutableSearch(steps, composed, path, tuple(blocked), rounds, True)
        index = _blocking_index(steps, path.blocker)
        step = steps[index]
        first_blocker = path.blocker
        if first_blocker.time_s == 0.0:
            # The start itself is blocked: no action from this candidate of con_1 can
            # run from this branch.
            refusal = refused(problem)
            if refusal:
                return ExecutableSearch(None, None, None, refusal, rounds, tried_a_start)
            blocked.append(InfeasibleSegment(step.j + 1, step.k + 1, first_blocker.reason,
                                             f"at con_{step.j + 1}, the start: {first_blocker.detail}",
                                             demo_names[step.demo]))
            problem.forbid_state(steps[0].j, steps[0].a_j)
            continue
        # Asked before the step's alternatives are followed one by one: a blocker no
        # choice can change refuses the task now (alternatives forbid nothing, so the
        # answer is the one the search would get after them).
        refusal = refused(problem)
        if refusal:
            return ExecutableSearch(None, None, None, refusal, rounds, tried_a_start)
        passed = False
        if alternatives is not None and step not in tried:
            tried.add(step)
            for option in alternatives(step):
                if (pose_blockers is not None and step_poses is not None
                        and pose_blockers.blocks_segment(*step_poses(step, option), step.j)):
                    continue  # its own poses show it blocked in its spans
                trial = dict(overrides)
                trial[step] = option
                composed, path = check(trial, range(step.j, step.k))
                if path is not None and (path.executable or _blocking_index(steps, path.blocker) > index):
                    overrides = trial  # this mapping gets the arm past the step
                    passed = True
                    break
        if passed:
            if path.executable:
                return ExecutableSearch(steps, composed, path, tuple(blocked), rounds, True)
            continue  # the next blocker is in a later step
        blocked.append(InfeasibleSegment(step.j + 1, step.k + 1, first_blocker.reason, first_blocker.detail,
                                         demo_names[step.demo]))
        problem.forbid(step)
        if forbidden is not None:
            forbidden.append(step)
    return ExecutableSearch(None, None, None, tuple(blocked), max_rounds, tried_a_start)


def _forbid_what_poses_block(problem: CompositionProblem, steps: list[Step], pose_blockers: PoseBlockers,
                             step_poses: Callable[[Step, tuple], tuple[np.ndarray, Sequence[int]]],
                             alternatives: Callable[[Step], list] | None) -> None:
    """Forbids, on this start, each of ``steps`` (forbidden on an earlier start) whose
    every mapping (the default and its alternatives) shows a blocker in its own spans by
    its poses on this start's branch: the search would pass over each of them and forbid
    the step, had it come to it; carried over, the planner is not offered it again. A
    step blocked on an earlier start by a follow, or by poses this branch does not
    share, is left to the search."""
    for step in steps:
        options = [(None, None)] + (alternatives(step) if alternatives is not None else [])
        if all(pose_blockers.blocks_segment(*step_poses(step, option), step.j) for option in options):
            problem.forbid(step)

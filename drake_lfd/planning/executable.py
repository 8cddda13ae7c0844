"""Executable compositions: the search keeps only compositions whose joint path passes.

A composition is planned in SE(3); whether the UR5e can run it shows only in joint
space. Checking every legal action's joint path would cost a follow of the controller's
law per action and start state, so the check is lazy, as lazy collision checking in
sampling planners: solve for the best composition, follow its whole joint path
(:meth:`~drake_lfd.robot.joint_path.JointPathChecker.follow_from_candidates`: every
inverse-kinematics branch and 2 pi winding of the start), and if it is blocked, forbid
the action (demo, span and candidate angles) whose span the first violation is in, and
solve again. Both planners choose only among the actions left, so the composition
returned is executable, or none is and every forbidden action is reported with its
reason.

A span's feasibility depends on the joint state it starts from; forbidding the action
for every start is the approximation that keeps the search small (an action blocked
after one prefix may run after another). The free twist of each span is already chosen
in SE(3) for clearance (``planner.map_span_clear``).

Not for: the joint-space check itself (``robot/joint_path.py``) or building the plan
(``planner.py``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from drake_lfd.planning.composition import CompositionProblem, Step
from drake_lfd.robot.joint_path import Blocker, JointPath, JointPathChecker

__all__ = ["MAX_SEARCH_ROUNDS", "InfeasibleSegment", "ExecutableSearch", "search_executable"]

# Solve-check-forbid rounds before giving up (each forbids one action).
MAX_SEARCH_ROUNDS = 40


@dataclasses.dataclass(frozen=True)
class InfeasibleSegment:
    """A segment of a composition that the robot cannot run, and why.

    ``con_from``/``con_to`` are 1-based; ``reason`` one of ``reach``, ``joint_limit``,
    ``singularity``, ``collision``; ``demo`` the demonstration mapped onto it (empty for a
    critical configuration out of reach before any composition)."""

    con_from: int
    con_to: int
    reason: str
    detail: str
    demo: str = ""

    def describe(self) -> str:
        demo = f" ({self.demo})" if self.demo else ""
        return f"con_{self.con_from} -> con_{self.con_to}{demo}: {self.reason}: {self.detail}"


@dataclasses.dataclass(frozen=True)
class ExecutableSearch:
    """The outcome of :func:`search_executable`.

    ``steps`` and ``composed`` (what ``compose`` returned for them) and ``joint_path``
    are None when nothing executes; ``blocked`` lists the forbidden segments, in the
    order they were found; ``rounds`` counts the compositions checked."""

    steps: list[Step] | None
    composed: tuple | None
    joint_path: JointPath | None
    blocked: tuple[InfeasibleSegment, ...]
    rounds: int


def _span_keys(steps: list[Step], overrides: dict) -> list:
    """One key per span (con to con): the step covering it, its mapping override and the
    span's place in it; equal keys mean the same mapped motion."""
    keys = []
    for step in steps:
        for offset in range(step.k - step.j):
            keys.append((step.demo, step.j, step.k, step.a_j, step.a_k, overrides.get(step), offset))
    return keys


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
) -> ExecutableSearch:
    """Lazy search for an executable composition (see the module docstring).

    ``solve(problem)`` returns the planner's composition or None; ``compose(steps,
    overrides)`` returns a tuple whose first item is the
    :class:`~drake_lfd.core.timing.TimedPlan`, ``overrides`` mapping a step's index to
    its ``(first_index, twist)``; ``alternatives(step)`` lists the other mappings of a
    step (demo suffix and twist) to try, best first, before the step is forbidden.
    ``problem`` is modified (forbidden actions).
    """
    blocked: list[InfeasibleSegment] = []
    overrides: dict[Step, tuple] = {}  # mappings adopted for steps, by step
    tried: set[Step] = set()  # steps whose alternatives were tried
    rounds = 0
    while rounds < max_rounds:
        rounds += 1
        steps = solve(problem)
        if steps is None:
            return ExecutableSearch(None, None, None, tuple(blocked), rounds - 1)

        def check(current: dict):
            composed = compose(steps, {i: current[s] for i, s in enumerate(steps) if s in current})
            timed = composed[0]
            starts = checker.start_candidates(timed.X_WE_list()[0])
            if not starts:
                return composed, None
            return composed, checker.follow_from_candidates(timed, starts, _span_keys(steps, current))

        composed, path = check(overrides)
        if path is None:
            # con_1 at this candidate has no collision-free joint configuration: no
            # action from it can run.
            step = steps[0]
            blocked.append(InfeasibleSegment(step.j + 1, step.k + 1, "reach",
                                             f"no collision-free joint configuration reaches con_{step.j + 1}",
                                             demo_names[step.demo]))
            problem.forbid_state(step.j, step.a_j)
            continue
        if path.executable:
            return ExecutableSearch(steps, composed, path, tuple(blocked), rounds)
        index = _blocking_index(steps, path.blocker)
        step = steps[index]
        first_blocker = path.blocker
        passed = False
        if alternatives is not None and step not in tried:
            tried.add(step)
            for option in alternatives(step):
                trial = dict(overrides)
                trial[step] = option
                composed, path = check(trial)
                if path is not None and (path.executable or _blocking_index(steps, path.blocker) > index):
                    overrides = trial  # this mapping gets the arm past the step
                    passed = True
                    break
        if passed:
            if path.executable:
                return ExecutableSearch(steps, composed, path, tuple(blocked), rounds)
            continue  # the next blocker is in a later step
        blocked.append(InfeasibleSegment(step.j + 1, step.k + 1, first_blocker.reason, first_blocker.detail,
                                         demo_names[step.demo]))
        problem.forbid(step)
    return ExecutableSearch(None, None, None, tuple(blocked), max_rounds)

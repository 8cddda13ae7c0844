"""The planning options: one value saying how a task is planned, with one default.

:class:`PlanningOptions` gathers every setting of planning that is a choice rather than a
per-call object: which planner (the exact shortest-path planner or the Q-policy's greedy
walk), which action cost (``"fidelity"``, or the paper's Eq. 31 ``"paper"``), whether
only executable compositions are planned (the plan-time joint-space check) and whether
the executable plan is refined by trajectory optimization, with the similarity
tolerances, the fidelity weights, the longest span, the Q-planner's refinement episodes
and the timing limits. Its defaults are those of ``drake-lfd plan`` (docs/cli.rst), so
the command line, :func:`drake_lfd.plan_task`, the planner system and the closed-loop
trials plan alike unless told otherwise; :meth:`PlanningOptions.paper_baseline` is the
paper's own setting (Eq. 31, no joint-space check).

What the options do not hold are the objects a call plans with: the Q-policy, the seed,
the floor height and the joint-space checker built for the task's work cell.

Not for: planning (:mod:`drake_lfd.planning.planner`) or building the checker
(:func:`drake_lfd.diagrams.pipeline.joint_path_checker`).
"""

from __future__ import annotations

import dataclasses

from drake_lfd.core.fidelity import FidelityWeights, check_cost_mode
from drake_lfd.core.option_values import PLANNERS
from drake_lfd.core.similarity import Tolerances
from drake_lfd.core.timing import DEFAULT_MAX_ANGULAR_SPEED_RAD_S, DEFAULT_MAX_SPEED_M_S, TimingLimits
from drake_lfd.planning.q_learning import DEFAULT_REFINE_EPISODES

__all__ = ["PLANNERS", "PlanningOptions"]


@dataclasses.dataclass(frozen=True)
class PlanningOptions:
    """How a task is planned (module docstring); frozen and hashable.

    Attributes
    ----------
    planner : {"exact", "q"}
        The exact shortest-path planner, or the greedy walk on a Q-policy (which then
        needs a policy, given per call).
    cost : {"fidelity", "paper"}
        The action cost both planners minimise: ``"fidelity"``, Eq. 31's total alpha
        plus the shape-fidelity terms weighted by ``fidelity_weights``
        (``core/fidelity.py``), or ``"paper"``, the paper's baseline (alpha alone; the
        fidelity terms only break its ties).
    refine : bool
        Refine the executable plan by trajectory optimization in a tube around the mapped
        demonstrations (:func:`drake_lfd.planning.refinement.refine_plan`); needs
        ``joint_check``.
    joint_check : bool
        Plan only executable compositions: the plan-time joint-space check of the task's
        work cell (``planning/executable.py``). Whoever builds the checker reads it
        (:func:`drake_lfd.plan_task`, the pipeline); the core planner checks with the
        checker it is given.
    tolerances : Tolerances
        The similarity tolerances of the legal actions (Eq. 19-21).
    fidelity_weights : FidelityWeights
        The weights of the shape-fidelity terms.
    max_span : int or None
        The most critical configurations one demonstration may span (None: no limit).
    refine_episodes : int
        Episodes the Q-planner refines its policy on the task before the greedy walk.
    max_speed_m_s, max_angular_speed_rad_s : float
        The geometric timing pass's tool speed limits (``core/timing.py``).
    timing : TimingLimits or None
        The limits of the time-optimal timing along a checked joint path (None: the
        task's ``timing`` block, else :class:`~drake_lfd.core.timing.TimingLimits`'s
        defaults).

    Raises
    ------
    ValueError
        An unknown planner or cost, a negative ``refine_episodes``, a ``max_span``
        below 1, or ``refine`` without ``joint_check``.
    """

    planner: str = "exact"
    cost: str = "fidelity"
    refine: bool = False
    joint_check: bool = True
    tolerances: Tolerances = Tolerances()
    fidelity_weights: FidelityWeights = FidelityWeights()
    max_span: int | None = None
    refine_episodes: int = DEFAULT_REFINE_EPISODES
    max_speed_m_s: float = DEFAULT_MAX_SPEED_M_S
    max_angular_speed_rad_s: float = DEFAULT_MAX_ANGULAR_SPEED_RAD_S
    timing: TimingLimits | None = None

    def __post_init__(self):
        if self.planner not in PLANNERS:
            raise ValueError(f"planner must be one of {PLANNERS}, got {self.planner!r}")
        check_cost_mode(self.cost)
        if self.refine and not self.joint_check:
            raise ValueError("refine needs joint_check (the refinement optimizes along the checked joint path)")
        if self.max_span is not None and not self.max_span >= 1:
            raise ValueError(f"max_span must be at least 1 or None, got {self.max_span!r}")
        if not self.refine_episodes >= 0:
            raise ValueError(f"refine_episodes must be non-negative, got {self.refine_episodes!r}")

    @classmethod
    def paper_baseline(cls, **changes) -> "PlanningOptions":
        """The paper's own setting: Eq. 31's cost (``cost="paper"``) and no joint-space
        check (``joint_check=False``), the rest at the defaults or as ``changes`` say
        (``PlanningOptions.paper_baseline(planner="q")``)."""
        return cls(**{"cost": "paper", "joint_check": False, **changes})

    def replace(self, **changes) -> "PlanningOptions":
        """These options with ``changes`` (checked again)."""
        return dataclasses.replace(self, **changes)

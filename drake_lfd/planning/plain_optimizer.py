"""The plain optimizer: the baseline ``--refine`` is compared with, Drake's kinematic
trajectory optimization of a plan without the demonstrations' tube.

:func:`plain_plan` runs the refinement's program and checks
(:mod:`drake_lfd.planning.refinement`) from straight joint-space lines between the
composed plan's configurations at its critical configurations (pinned at the same path
fractions), with no tube: what the demonstrations add is the difference
(``benchmarks/bench_refinement.py``).

Not for: the refinement itself or its program (``refinement.py``,
``robot/trajectory_optimization.py``).
"""

from __future__ import annotations

from drake_lfd.planning.planner import PlanResult
from drake_lfd.planning.refinement import optimize_plan
from drake_lfd.planning.refinement_options import RefinementOptions
from drake_lfd.robot.joint_path import JointPathChecker
from drake_lfd.robot.optimization_scene import OptimizationScene

__all__ = ["plain_plan"]


def plain_plan(result: PlanResult, checker: JointPathChecker, *, scene: OptimizationScene | None = None,
               options: RefinementOptions = RefinementOptions()) -> PlanResult:
    """The plain optimizer's plan, like :func:`refine_plan` but without the tube, from
    straight joint-space lines between ``result``'s configurations at its critical
    configurations (pinned at the same path fractions)."""
    return optimize_plan(result, checker, scene, options, "plain")

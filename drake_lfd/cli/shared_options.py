"""Options several ``drake-lfd`` commands share, as argparse parent parsers.

``plan``, ``simulate`` and ``sweep`` take the task, the library and the planner's
options (:func:`planning_parent`); ``simulate``, ``sweep`` and ``paper`` run closed-loop
trials on worker processes or a cluster (:func:`workers_parent`, :func:`workers_of`).
Each command passes the parents it needs (``subparsers.add_parser(..., parents=[...])``),
so an option is declared, with its help text and default, once.

Plain Python, like every parser module: ``--help`` and a bad flag are answered before
Drake is imported. Not for: what the options do (the command modules).
"""

from __future__ import annotations

import argparse

from drake_lfd.cli.argument_checks import library_help, require_at_least
from drake_lfd.core.option_values import COST_MODES, PLANNERS, default_workers

__all__ = ["planning_parent", "workers_parent", "workers_of"]


def planning_parent() -> argparse.ArgumentParser:
    """The task, library and planner options ``plan``, ``simulate`` and ``sweep`` share."""
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("task", metavar="TASK.yaml", help="the task file (docs/task_files.rst)")
    parser.add_argument("--library", required=True, metavar="LIB",
                        help=library_help() + "; its X_tool0_E must equal the task's")
    parser.add_argument("--planner", choices=PLANNERS, default="exact",
                        help="exact shortest-path planner, or the greedy walk on a Q-policy")
    parser.add_argument("--policy", metavar="POLICY", help="Q-policy file (needed by --planner q)")
    parser.add_argument("--cost", choices=COST_MODES, default="fidelity",
                        help="the action cost the planner minimises: the paper's Eq. 31 (total rotation "
                             "distance), or fidelity, which also charges how far each demonstration is bent and "
                             "stretched by its mapping (docs/method.rst, Shape fidelity)")
    parser.add_argument("--refine", action="store_true",
                        help="refine the executable plan by trajectory optimization in a tube around the "
                             "mapped demonstrations (docs/method.rst, Refinement by trajectory optimization); "
                             "when it fails the unrefined plan stands, with the reason (default: off)")
    parser.add_argument("--allow-policy-mismatch", action="store_true",
                        help="plan with a policy trained on other demonstrations than the library's "
                             "(default: refused; with this, a warning)")
    return parser


def workers_parent() -> argparse.ArgumentParser:
    """``--workers N | --scheduler ADDRESS``: where the closed-loop trials run."""
    parser = argparse.ArgumentParser(add_help=False)
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int, metavar="N",
                       help="worker processes running the closed-loop trials in parallel, one single-threaded "
                            "process per core; 1 runs them one after another in this process (default: every "
                            "core, at most one per trial)")
    group.add_argument("--scheduler", metavar="ADDRESS",
                       help="run the trials on the workers of a running dask.distributed scheduler "
                            "(tcp://host:8786; docs/cli.rst, Sweeps on a cluster) instead of local processes")
    return parser


def workers_of(args, trials: int) -> int:
    """``--workers`` checked (>= 1), or its default: every core, at most one per trial."""
    if args.workers is None:
        return default_workers(trials)
    return require_at_least(args.workers, 1, "--workers")

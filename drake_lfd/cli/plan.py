"""``drake-lfd plan``: one SE(3) motion plan for a task, or a demonstration request.

A thin front end (docs/cli.rst): it loads the task and the library, refreshes the
library's feature caches, plans and prints. Not for: planning itself
(:mod:`drake_lfd.planning.planner`) or the plan's JSON (:mod:`drake_lfd.io.plan_json`).
"""

from __future__ import annotations

import sys
from pathlib import Path

from drake_lfd.cli.argument_checks import prepare_output, require_seed
from drake_lfd.cli.shared_options import planning_parent
from drake_lfd.cli.startup import interrupts_deferred
from drake_lfd.core.errors import EXIT_DEMONSTRATION_REQUESTED, EXIT_NO_EXECUTABLE_PLAN, InputError
from drake_lfd.io.task_checks import precheck_task_file


__all__ = ["add_parser", "load_policy_for", "planning_options_of", "request_script_path", "run"]


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "plan",
        parents=[planning_parent()],
        help="plan one SE(3) motion for a task, or request a demonstration",
        description=(
            "Plan one concrete trial of TASK.yaml with the library's demonstrations. "
            "Exit 3 with the uncovered segments when the library cannot cover the task."
        ),
    )
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="draws the trial's ranged positions; seeds the Q-planner's refinement")
    parser.add_argument("--request-script", metavar="SCRIPT.yaml",
                        help="when a demonstration is requested, write a guidance script for "
                             "drake-lfd record showing the missing motion (one file per missing segment: "
                             "SCRIPT_con_J_con_K.yaml when there are several) (default: not written)")
    parser.add_argument("--json", metavar="OUT",
                        help="write the plan or the request as JSON (missing folders are created)")
    parser.set_defaults(func=run)


def load_policy_for(args, library=None):
    """The Q-policy named by ``--policy`` (None for the exact planner).

    With ``library``, the policy is checked against its demonstrations
    (:func:`~drake_lfd.io.policy_files.check_policy_library`): one trained on other
    demonstrations is refused, or with ``--allow-policy-mismatch`` used with a warning
    on stderr."""
    from drake_lfd.io.library import library_features
    from drake_lfd.io.policy_files import check_policy_library, load_policy
    from drake_lfd.planning.q_learning import Q_PLANNER_MAX_DEMOS

    if args.planner != "q":
        return None
    if library is not None and len(library.names) > Q_PLANNER_MAX_DEMOS:  # counted, no feature read
        raise InputError(f"--planner q serves libraries of at most {Q_PLANNER_MAX_DEMOS:,} demonstrations and "
                         f"{library.label} has {len(library.names):,}; use --planner exact",
                         field="--planner")
    if not args.policy:
        raise InputError("--planner q needs --policy POLICY (train one with drake-lfd train)", field="--policy")
    policy = load_policy(args.policy)
    if library is not None:
        warning = check_policy_library(
            policy, library_features(library), file=args.policy, library=library.label,
            allow_mismatch=getattr(args, "allow_policy_mismatch", False),
        )
        if warning:
            print(f"drake-lfd {args.command}: warning: {args.policy}: {warning}", file=sys.stderr)
    return policy


def request_script_path(request_script: str, segment, count: int) -> Path:
    """Where ``--request-script`` writes the guidance script of ``segment`` (one of
    ``count`` uncovered segments): the path given, or ``SCRIPT_con_J_con_K.yaml`` beside
    it when there are several."""
    path = Path(request_script)
    if count > 1:
        path = path.with_name(f"{path.stem}_con_{segment.con_from}_con_{segment.con_to}{path.suffix or '.yaml'}")
    return path


def planning_options_of(args):
    """The :class:`~drake_lfd.planning.options.PlanningOptions` of ``--planner``,
    ``--cost`` and ``--refine`` (the rest at their defaults, the joint-space check on)."""
    from drake_lfd.planning.options import PlanningOptions

    return PlanningOptions(planner=args.planner, cost=args.cost, refine=args.refine)


def run(args) -> int:
    require_seed(args.seed)
    prepare_output(args.json, "--json")
    prepare_output(args.request_script, "--request-script")
    precheck_task_file(args.task)  # a missing file, a typo'd key, a value out of range: before Drake loads
    with interrupts_deferred():
        import numpy as np

        from drake_lfd.core.tasks import draw_trial
        from drake_lfd.experiments.planning_api import plan_task
        from drake_lfd.io.library import Library, check_end_effector_frame
        from drake_lfd.io.plan_json import describe_infeasible, describe_uncovered, plan_json
        from drake_lfd.io.strict_json import write_json
        from drake_lfd.io.task_files import load_task

    options = planning_options_of(args)
    task = load_task(args.task)
    library = Library.open(args.library)
    check_end_effector_frame(library, task.X_tool0_E, file=args.task)
    policy = load_policy_for(args, library)
    trial = draw_trial(task, args.seed)
    library.write_feature_caches()
    # Planned in the work cell the pipeline of ``simulate`` builds, checked as its
    # controller will be, so this plan is the one it runs.
    result = plan_task(trial, library, options, policy=policy, seed=args.seed)
    script_paths = [request_script_path(args.request_script, u, len(result.uncovered)) for u in result.uncovered
                    ] if args.request_script else None
    if args.json:
        write_json(Path(args.json), plan_json(result, cost=options.cost, script_paths=script_paths))
    if result.planned:
        chain = " + ".join(f"{s.demo} (con_{s.con_from}->con_{s.con_to})" for s in result.composition)
        print(f"{task.name}: planned with {chain}; total cost {result.total_cost:.3f}, "
              f"{len(result.timed.times)} poses over {result.timed.duration:.1f} s, "
              f"largest correction {result.max_correction_position_m * 1e3:.1f} mm / "
              f"{np.degrees(result.max_correction_rotation_rad):.1f} deg")
        for s in result.composition:
            print(f"  {s.demo} (con_{s.con_from}->con_{s.con_to}): largest correction "
                  f"{s.max_correction_position_m * 1e3:.1f} mm / {np.degrees(s.max_correction_rotation_rad):.1f} deg")
        if result.fallback:
            print(f"note: the greedy Q-walk dead-ended; the {result.fallback} planner completed the plan")
        if result.refinement is not None:
            print(result.refinement.describe())
        return 0
    if result.status == "no_executable_plan":
        # One line per blocking segment (the library covers the task; the UR5e cannot
        # run any composition of it).
        for line in describe_infeasible(result):
            print(f"{task.name}: no executable plan: {line}"[:300], file=sys.stderr)
        return EXIT_NO_EXECUTABLE_PLAN
    print(f"{task.name}: library {library.label} cannot cover the task; please demonstrate:")
    for line in describe_uncovered(result):
        print("  " + line)
    if args.request_script:
        from drake_lfd.io.atomic_files import atomic_write_bytes
        from drake_lfd.io.guidance_scripts import request_guidance_yaml

        for u, path in zip(result.uncovered, script_paths):
            atomic_write_bytes(path, request_guidance_yaml(trial, u, path=path).encode())
            print(f"  guidance script for drake-lfd record (edit it to show how): {path}")
    else:
        print("  (--request-script SCRIPT.yaml writes a guidance script of it for drake-lfd record)")
    return EXIT_DEMONSTRATION_REQUESTED

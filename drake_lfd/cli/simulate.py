"""``drake-lfd simulate``: closed-loop UR5e runs of N concrete trials of a task.

A thin front end (docs/cli.rst): it checks every output path first, loads the task and
the library, refreshes the library's feature caches, runs the trials and writes what was
asked. With ``--json OUT.json`` each finished trial is also appended, as it finishes, to
``OUT.jsonl`` (:mod:`drake_lfd.io.json_lines`), so an interrupt (Ctrl-C, SIGTERM) or a
late error keeps every trial that ran; the per-trial lines printed so far are printed
then too. With ``--workers N`` (default: every core) or ``--scheduler`` the trials run on
worker processes (:mod:`drake_lfd.experiments.parallel_trials`), with the same results in
trial order. Not for: running or judging trials (:mod:`drake_lfd.experiments.simulation`).
"""

from __future__ import annotations

from pathlib import Path

from drake_lfd.cli.argument_checks import prepare_output, require_at_least, require_meshcat, require_seed
from drake_lfd.io.json_lines import JsonLinesFile, json_lines_path_for
from drake_lfd.io.strict_json import write_json
from drake_lfd.core.errors import EXIT_DEMONSTRATION_REQUESTED, EXIT_NO_EXECUTABLE_PLAN, EXIT_OK, InputError
from drake_lfd.cli.plan import load_policy_for, planning_options_of
from drake_lfd.cli.shared_options import planning_parent, workers_of, workers_parent
from drake_lfd.cli.startup import interrupts_deferred
from drake_lfd.io.task_checks import precheck_people_file, precheck_task_file


__all__ = ["add_parser", "run", "CONTROLLER_CHOICES"]

# ``--controller`` values: the controller methods of a task's ``simulation.controller``.
CONTROLLER_CHOICES = {"compiled": "compiled", "drake": "drake", "paper": "pseudo_inverse"}


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "simulate",
        parents=[planning_parent(), workers_parent()],
        help="plan and run N concrete trials of a task closed loop on a simulated UR5e",
        description=(
            "Draw N concrete trials of TASK.yaml (trial i uses seed S + i), plan each with the "
            "library, track the plan with differential IK on a simulated UR5e, monitor the "
            "safety shells, and judge each run (docs/method.rst, Closed loop and success)."
        ),
    )
    parser.add_argument("--trials", type=int, default=1, metavar="N", help="number of trials, >= 1")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="the first trial's seed (trial i, from 0, uses S + i)")
    parser.add_argument("--json", metavar="OUT",
                        help="write the results, every failure reason in full, as JSON (missing folders are created); "
                             "each trial is also appended to OUT's .jsonl file as it finishes")
    parser.add_argument("--html", metavar="REC.html",
                        help="write a Meshcat recording of the first trial that runs (missing folders are created)")
    parser.add_argument("--meshcat", action="store_true",
                        help="show every trial live in a Meshcat viewer as it runs (prints the address to open "
                             "in a browser; needs Drake's meshcat network access) (default: off)")
    parser.add_argument("--figures", metavar="DIR",
                        help="write figures of the first trial that ran into DIR (created if missing): "
                             "SE(3) plan, joints, distance to shells, and with people the separation and speed override")
    parser.add_argument("--people", metavar="FILE.yaml",
                        help="people in the cell for every trial: a YAML file with people: (each a name and a path "
                             "of timed floor waypoints or a recorded track) and optionally collaboration: (ISO/TS "
                             "15066 speed and separation monitoring parameters); replaces the task's own people "
                             "(docs/collaboration.rst)")
    parser.add_argument("--controller", choices=sorted(CONTROLLER_CHOICES), default=None,
                        help="compiled: the plan's checked joint path tracked by Drake's C++ systems (the default); "
                             "drake: the Python task-space controller with Drake's differential IK; paper: the "
                             "Python controller with the paper's pseudo-inverse (Eq. 35-38) (default: the task's, "
                             "compiled unless its simulation block says otherwise)")
    parser.set_defaults(func=run)


def run(args) -> int:
    require_at_least(args.trials, 1, "--trials")
    require_seed(args.seed)
    if args.html:
        require_meshcat("--html")
    if args.meshcat:
        require_meshcat("--meshcat")
        if args.scheduler or (args.workers or 1) > 1:
            raise InputError("shows the trials one after another in one viewer: it needs --workers 1",
                             field="--meshcat")
    workers = 1 if args.meshcat else workers_of(args, args.trials)
    controller = None if args.controller is None else CONTROLLER_CHOICES[args.controller]
    prepare_output(args.json, "--json")
    prepare_output(args.html, "--html")
    prepare_output(args.figures, "--figures", folder=True)
    # Every problem the files' text shows (a missing file, a typo'd key, a value out of
    # range), before Drake loads; the people file's when the task file's were all checked.
    if precheck_task_file(args.task) and args.people:
        precheck_people_file(args.people)
    with interrupts_deferred():
        from drake_lfd.io.library import Library, check_end_effector_frame, library_features
        from drake_lfd.cli.progress import ProgressBar
        from drake_lfd.experiments.simulation import (
            run_trials, simulate_json, trial_record, trial_summary_line, write_trial_figures,
        )
        from drake_lfd.io.people_files import task_with_people
        from drake_lfd.io.task_files import load_task
    options = planning_options_of(args)
    task = load_task(args.task)
    if args.people:
        task = task_with_people(task, args.people)
    if task.people and (controller or task.simulation.controller.method) != "compiled":
        raise InputError("people in the cell need the compiled controller", field="--controller")
    library = Library.open(args.library)
    check_end_effector_frame(library, task.X_tool0_E, file=args.task)
    policy = load_policy_for(args, library)
    lines = []
    finished = JsonLinesFile(json_lines_path_for(args.json)) if args.json else None
    try:
        bar = ProgressBar("trials", args.trials)

        def progress(done, total, outcome):
            line = trial_summary_line(outcome, task)
            record = trial_record(task, outcome) if finished is not None else None
            # The record on disk and the line printed on an interrupt go together: a Ctrl-C
            # waits for both, and a failed write prints nothing.
            with interrupts_deferred():
                if finished is not None:
                    finished.append(record)
                lines.append(line)
            bar.update(done, "ok" if outcome.success else "failed")

        library.write_feature_caches()
        meshcat = None
        if args.meshcat:
            from pydrake.geometry import Meshcat

            meshcat = Meshcat()
            print(f"{task.name}: Meshcat viewer at {meshcat.web_url()} (open it in a browser)", flush=True)
        if workers == 1 and args.scheduler is None:
            outcomes, wall = run_trials(
                task, library_features(library), trials=args.trials, seed=args.seed, options=options,
                policy=policy, record_html=args.html, progress=progress, meshcat=meshcat, controller=controller,
            )
        else:  # the same trials on worker processes or a cluster, delivered in trial order
            from drake_lfd.experiments.parallel_trials import run_trials_on_workers, runner_spec

            runner = runner_spec(args.task, library, policy_file=args.policy if args.planner == "q" else None,
                                 options=options, controller=controller, people_file=args.people)
            outcomes, wall = run_trials_on_workers(
                runner, trials=args.trials, seed=args.seed, record_html=args.html, progress=progress,
                workers=workers, scheduler=args.scheduler,
            )
        bar.close()
    except BaseException:
        # Interrupted (or failed) part-way: say what finished and where it is kept.
        for line in lines:
            print(line, flush=True)
        on_disk = finished.records_on_disk() if finished is not None else 0
        if on_disk:
            print(f"{task.name}: {on_disk} finished trial(s) of {args.trials} are in {finished.path}",
                  flush=True)
        raise
    finally:
        if finished is not None:
            finished.close()
    document = simulate_json(task, outcomes, wall)
    first = next((o for o in outcomes if o.run is not None), None)
    if args.figures and first is not None:
        write_trial_figures(task, first, Path(args.figures), task.name)
    if args.json:
        write_json(Path(args.json), document)
    for line in lines:
        print(line)
    lost = [o.run.collaboration.time_lost_s for o in outcomes if getattr(o.run, "collaboration", None)]
    people = f"; people cost {sum(lost):.1f} s in all" if lost else ""
    print(f"{task.name}: {document['success_count']}/{args.trials} trials succeeded "
          f"({document['sim_time_s']:.1f} s simulated in {wall:.1f} s{people})")
    # 0: every trial succeeded; 3: every trial needs a demonstration the library lacks;
    # 4: anything else (a trial without an executable plan, or one that failed).
    if outcomes and all(o.success for o in outcomes):
        return EXIT_OK
    if outcomes and all(o.plan is not None and o.plan.status == "demonstration_requested" for o in outcomes):
        return EXIT_DEMONSTRATION_REQUESTED
    if all(o.run is None and o.plan is not None and o.plan.planned for o in outcomes):
        raise InputError(outcomes[0].failures[0] if outcomes[0].failures else "no trial could run",
                         file=args.task)
    return EXIT_NO_EXECUTABLE_PLAN

"""``drake-lfd sweep``: N trials of a task at every robot base placement of a grid, in parallel.

A thin front end (docs/cli.rst): it checks the options, loads the task and the library,
runs every (base placement, trial) on worker processes or a cluster
(:mod:`drake_lfd.experiments.parallel_trials`) and appends each finished trial to
``DIR/sweep.jsonl`` as it finishes; ``--resume`` keeps the rows already there and runs the
rest. At the end: ``DIR/summary.json`` and three figures
(:mod:`drake_lfd.experiments.sweep`). Also home of the ``--workers``/``--scheduler``
options that ``simulate`` and ``paper`` share. Not for: running or judging trials.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

from drake_lfd.cli.argument_checks import prepare_output, require_at_least, require_seed
from drake_lfd.cli.plan import load_policy_for
from drake_lfd.cli.shared_options import planning_parent, workers_of, workers_parent
from drake_lfd.cli.startup import interrupts_deferred
from drake_lfd.core.errors import InputError
from drake_lfd.io.atomic_files import fsync_directory
from drake_lfd.io.json_lines import JsonLinesFile, read_json_lines
from drake_lfd.io.task_checks import precheck_task_file

__all__ = ["add_parser", "runner_options_of", "settings_options_of", "run",
           "SWEEP_ROWS", "SUMMARY"]

SWEEP_ROWS = "sweep.jsonl"
SUMMARY = "summary.json"
FIGURES = ("success_by_base.png", "success_by_variable.png", "failure_reasons.png")
_NEGATIVE_AXIS = re.compile(r"^-\.?\d\S*$")


def runner_options_of(args) -> dict:
    """The RunnerSpec keyword options of the command's flags: ``options``, the
    :class:`~drake_lfd.planning.options.PlanningOptions` of ``--planner``, ``--cost`` and
    ``--refine`` (built once), and ``controller`` when the command has ``--controller``."""
    from drake_lfd.cli.plan import planning_options_of

    options = {"options": planning_options_of(args)}
    if hasattr(args, "controller"):
        options["controller"] = args.controller
    return options


def settings_options_of(runner_options: dict) -> dict:
    """The options as ``summary.json``'s settings record them: ``planner``, ``cost``,
    ``refine`` (and ``controller`` when the command sets it)."""
    planning = runner_options["options"]
    settings = {"planner": planning.planner, "cost": planning.cost, "refine": planning.refine}
    if "controller" in runner_options:
        settings["controller"] = runner_options["controller"]
    return settings


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        "sweep",
        parents=[planning_parent(), workers_parent()],
        help="run N trials of a task at every robot base placement of a grid, in parallel, with a success map",
        description=(
            "Move the task's robot base over a grid (x, y in m, optionally z in m and yaw in deg), run N "
            "concrete trials of TASK.yaml at each placement (trial i uses seed S + i) on worker processes "
            "or a cluster, write each finished trial to DIR/sweep.jsonl, then DIR/summary.json and figures "
            "of the success rate over the grid, over the task's variables and the failures by kind."
        ),
    )
    parser.add_argument("--trials", type=int, default=1, metavar="N", help="trials per base placement, >= 1")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="the first trial's seed (trial i, from 0, uses S + i, at every placement)")
    parser.add_argument("--base-grid", nargs="+", metavar="A0:A1:N",
                        help="the base placements: X0:X1:NX Y0:Y1:NY [Z0:Z1:NZ] [YAW0:YAW1:NYAW], N evenly "
                             "spaced values from A0 to A1 per axis (m, m, m, deg); axes not given keep the task "
                             "file's base (default: only the task file's base)")
    # A grid axis may start with a minus ("-0.3:-0.1:5"): argparse takes such a word for an
    # option unless it looks like a negative number, so an axis counts as one here.
    parser._negative_number_matcher = _NEGATIVE_AXIS
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="output folder (created if missing): sweep.jsonl (each trial as it finishes), "
                             "summary.json, success_by_base.png, success_by_variable.png, failure_reasons.png")
    parser.add_argument("--resume", action="store_true",
                        help="keep the trials already in DIR/sweep.jsonl (matched by their inputs) and run only "
                             "the rest (default: start DIR/sweep.jsonl afresh)")
    parser.set_defaults(func=run)


class _ContinuedJsonLines(JsonLinesFile):
    """A JSON-lines file continued at its end (``--resume``): a last line cut short by an
    interrupt is dropped first, so the next record starts on a line of its own."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.count = 0
        with open(self.path, "rb+") as file:
            data = file.read()
            if data and not data.endswith(b"\n"):
                file.truncate(data.rfind(b"\n") + 1)
        self._file = open(self.path, "a", encoding="utf-8")
        fsync_directory(self.path.parent)


def run(args) -> int:
    start = time.perf_counter()
    require_at_least(args.trials, 1, "--trials")
    require_seed(args.seed)
    if args.workers is not None:
        require_at_least(args.workers, 1, "--workers")
    out = prepare_output(args.out, "--out", folder=True)
    precheck_task_file(args.task)  # a missing file, a typo'd key, a value out of range: before Drake loads
    with interrupts_deferred():
        from drake_lfd.cli.progress import ProgressBar
        from drake_lfd.core.tasks import draw_trial
        from drake_lfd.experiments import sweep
        from drake_lfd.experiments.parallel_trials import BasePlacement, run_trial_specs, runner_spec, trial_specs
        from drake_lfd.io.library import Library, check_end_effector_frame, library_features
        from drake_lfd.io.strict_json import write_json
        from drake_lfd.io.task_files import load_task
        from drake_lfd.planning.problem_size import check_problem_size
    task = load_task(args.task)
    task_base = BasePlacement.of(task.X_WB)
    grid = sweep.base_grid(args.base_grid, task_base)
    library = Library.open(args.library)
    check_end_effector_frame(library, task.X_tool0_E, file=args.task)
    load_policy_for(args, library)
    library.write_feature_caches()
    check_problem_size(task, library_features(library))
    policy = str(Path(args.policy).resolve()) if args.planner == "q" else None

    specs, rows_of = [], {}
    variables = {seed: draw_trial(task, seed).variable_values for seed in range(args.seed, args.seed + args.trials)}
    options = runner_options_of(args)
    for placement in grid.placements():
        runner = runner_spec(args.task, library, policy_file=policy, base=placement, **options)
        for spec in trial_specs(runner, trials=args.trials, seed=args.seed):
            specs.append(spec)

    def row_of(spec, outcome) -> dict:
        return sweep.sweep_row(task_name=task.name, library=library.label, options=spec.runner.options_json(),
                               policy=policy, base=spec.runner.base, variables=variables[spec.seed], outcome=outcome)

    def key_of(spec) -> tuple:
        base = spec.runner.base
        return sweep.row_key({"task": task.name, "library": library.label, "options": spec.runner.options_json(),
                              "policy": policy, "base_x": base.x, "base_y": base.y, "base_z": base.z,
                              "base_yaw_deg": base.yaw_deg, "trial": spec.trial, "seed": spec.seed})

    keys = [key_of(spec) for spec in specs]
    wanted = set(keys)
    path = out / SWEEP_ROWS
    if args.resume and path.is_file():
        for row in read_json_lines(path):
            try:
                key = sweep.row_key(row)
            except (KeyError, TypeError, ValueError):
                raise InputError("is not a sweep's rows (a row without its inputs); run without --resume to "
                                 "start afresh", file=str(path)) from None
            if key in wanted:
                rows_of[key] = row
        rows_file = _ContinuedJsonLines(path)
    else:
        rows_file = JsonLinesFile(path)
    remaining = [spec for spec, key in zip(specs, keys) if key not in rows_of]
    kept = len(specs) - len(remaining)
    workers = 1 if args.scheduler is None and not remaining else workers_of(args, len(remaining))
    where = f"scheduler {args.scheduler}" if args.scheduler else f"{workers} worker(s)"
    print(f"{task.name}: {len(grid.placements())} base placement(s) x {args.trials} trial(s) = {len(specs)} "
          f"trials" + (f", {kept} already in {path}" if kept else "") + f"; {len(remaining)} to run on {where}",
          flush=True)
    try:
        bar = ProgressBar("trials", len(specs))
        bar.update(kept)

        def on_result(done, total, spec, outcome):
            row = row_of(spec, outcome)
            rows_file.append(row)
            rows_of[key_of(spec)] = row
            bar.update(kept + done, "ok" if outcome.success else "failed")

        run_trial_specs(remaining, workers=workers, scheduler=args.scheduler, on_result=on_result)
        bar.close()
    except BaseException:
        on_disk = sum(1 for row in read_json_lines(path) if _key_or_none(sweep, row) in wanted)
        print(f"{task.name}: {on_disk} of {len(specs)} trials are in {path}; run again with --resume to continue",
              flush=True)
        raise
    finally:
        rows_file.close()
    rows = [rows_of[key] for key in keys]
    summary = sweep.sweep_summary(rows, grid=grid, task_base=task_base, settings={
        "task": task.name, "task_file": str(Path(args.task).resolve()), "library": library.label,
        "options": settings_options_of(options), "policy": policy, "trials_per_base": args.trials, "seed": args.seed,
        "workers": None if args.scheduler else workers, "scheduler": args.scheduler,
        "wall_time_s": time.perf_counter() - start,
    })
    write_json(out / SUMMARY, summary)
    title = f"{task.name}, {library.label}, {args.trials} trial(s) per placement"
    sweep.success_by_base_figure(out / FIGURES[0], summary, title=f"{title}: success by base placement")
    sweep.success_by_variable_figure(out / FIGURES[1], rows, title=f"{title}: success by variable")
    sweep.failure_reasons_figure(out / FIGURES[2], summary, title=f"{title}: failures by kind")
    best = summary["best"][0]
    print(f"{task.name}: {summary['success_count']}/{len(rows)} trials succeeded; best base placement "
          f"x {best['base_x']:.3f} y {best['base_y']:.3f} z {best['base_z']:.3f} m yaw {best['base_yaw_deg']:.1f} deg: "
          f"{best['successes']}/{best['trials']}"
          + (f" ({len(summary['best'])} placements tie)" if len(summary["best"]) > 1 else "")
          + f". Summary: {out / SUMMARY}", flush=True)
    return 0


def _key_or_none(sweep, row):
    try:
        return sweep.row_key(row)
    except (KeyError, TypeError, ValueError):
        return None
